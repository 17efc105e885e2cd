#!/usr/bin/env bash
# Documentation check: the README is a short front page and the pages under
# docs/ say what is true now; history and measurements live in
# bench/RESULTS.md. Prints one line per problem, `path:line: what`, and
# exits 1 if there is any:
#
#  1. README.md has at most 200 lines.
#  2. README.md names the test command, `./build.sh test` (what CI runs).
#  3. README.md and docs/*.md carry no history markers: "issue N",
#     "the new default", a date (YYYY-MM-DD).
#  4. Every relative markdown link `](path)` or `](path#anchor)` in them
#     points at a file that exists, and an anchor into a .md file (or a
#     pure `#anchor`) at one of its headings (GitHub's slugs). http(s) and
#     mailto links are not checked. Links inside code are not links.
#  5. Every docs/*.md page is linked from README.md.
#
# usage: docs_check.sh [SOURCE_DIR]   (default: the folder above this script)

set -u
root=${1:-$(cd "$(dirname "$0")/.." && pwd)}
cd "$root" || { echo "docs_check: cannot enter $root"; exit 2; }

max_readme_lines=200
fail=0
say() { echo "$1"; fail=1; }

pages=()
for f in docs/*.md; do [ -e "$f" ] && pages+=("$f"); done
files=(README.md "${pages[@]}")

if [ ! -f README.md ]; then
    echo "README.md:0: missing"
    exit 1
fi

# 1. length
n=$(wc -l < README.md)
if [ "$n" -gt "$max_readme_lines" ]; then
    say "README.md:$((max_readme_lines + 1)): $n lines, at most $max_readme_lines: move the details to a page under docs/"
fi

# 2. the test command
if ! grep -qF './build.sh test' README.md; then
    say "README.md:1: does not name the test command \`./build.sh test\`"
fi

# 3. history markers
markers=('[Ii]ssue [0-9]+' '[Tt]he new default' '20[0-9][0-9]-[0-9][0-9]-[0-9][0-9]')
for f in "${files[@]}"; do
    for m in "${markers[@]}"; do
        while IFS= read -r hit; do
            [ -n "$hit" ] || continue
            what=$(printf '%s\n' "${hit#*:}" | grep -oE -- "$m" | head -n 1)
            say "$f:${hit%%:*}: history marker '$what': say what is true now; history and figures go to bench/RESULTS.md"
        done < <(grep -nE -- "$m" "$f")
    done
done

# The links of a markdown file, outside fenced code and inline code:
# "LINE<TAB>TARGET" per link.
links() {
    awk '
    /^[ \t]*(```|~~~)/ { fence = !fence; incode = 0; next }
    fence { next }
    /^[ \t]*$/ { incode = 0; next }
    {
        out = ""
        for (i = 1; i <= length($0); i++) {
            c = substr($0, i, 1)
            if (c == "`") { incode = !incode; continue }
            if (!incode) out = out c
        }
        while (match(out, /\]\([^) \t]+\)/)) {
            print NR "\t" substr(out, RSTART + 2, RLENGTH - 3)
            out = substr(out, RSTART + RLENGTH)
        }
    }' "$1"
}

# The heading anchors of a markdown file, as GitHub makes them.
slugs() {
    awk '
    /^[ \t]*(```|~~~)/ { fence = !fence; next }
    fence { next }
    /^#+[ \t]/ {
        h = $0
        sub(/^#+[ \t]+/, "", h)
        sub(/[ \t]+#*[ \t]*$/, "", h)
        h = tolower(h)
        gsub(/[^a-z0-9 _-]/, "", h)
        gsub(/ /, "-", h)
        s = h
        if (h in seen) s = h "-" seen[h]
        seen[h]++
        print s
    }' "$1"
}

# 4. links
declare -A linked=()
for f in "${files[@]}"; do
    dir=$(dirname "$f")
    while IFS=$'\t' read -r line target; do
        [ -n "$target" ] || continue
        case "$target" in
            http://* | https://* | mailto:*) continue ;;
        esac
        path=${target%%#*}
        anchor=
        [ "$path" != "$target" ] && anchor=${target#*#}
        if [ -z "$path" ]; then
            dest=$f
        else
            dest=$dir/$path
            dest=${dest#./}
            if [ ! -e "$dest" ]; then
                say "$f:$line: link to '$target': no such file $dest"
                continue
            fi
        fi
        [ "$f" = README.md ] && linked[$(realpath -m "$dest")]=1
        if [ -n "$anchor" ] && [[ "$dest" == *.md ]]; then
            if ! slugs "$dest" | grep -qxF -- "$anchor"; then
                say "$f:$line: link to '$target': $dest has no heading with anchor #$anchor"
            fi
        fi
    done < <(links "$f")
done

# 5. every page linked from the README
for p in "${pages[@]}"; do
    if [ -z "${linked[$(realpath -m "$p")]:-}" ]; then
        say "$p:1: not linked from README.md: add it to the README's index of pages"
    fi
done

exit $fail
