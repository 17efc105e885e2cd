#!/usr/bin/env bash
# Layering check (DESIGN.md "Modules", "Layering"): prints one line per
# violation, `path:line: what`, and exits 1 if there is any.
#
#  1. Library code (every module folder but cli/, tests/ and bench/) never
#     prints, reads the environment or touches process-wide state: no
#     printf, puts, perror, putchar, fprintf/fputs/... on stdout or stderr,
#     std::cout/cerr, getenv, setenv/putenv, srand, pthread_attr_setstacksize
#     or pthread_setattr_default_np (snprintf and vsnprintf are fine). A
#     plain grep: lines that begin a comment (or continue one with " * ")
#     and comments at the end of a line are left out; a call inside a
#     string or in a comment line that does not look like one is not.
#  2. A module #includes only its own headers and the public headers
#     (mim_<module>.h, mim_<module>_*.h) of the modules it may use (the
#     table below), never another module's private headers, and its
#     target_link_libraries(mim_<module> ...) names only those modules.
#  3. Every module folder is in the table.
#
# usage: check_layering.sh [SOURCE_DIR]   (default: the folder above this script)

# ---- who may use whom: "module: modules it may use" ----
# From DESIGN.md: core/ at the bottom, uses nothing; the computation modules
# (transfer, index, register, vest, sample's algorithms) use core;
# register/ builds on transfer/'s Laplacian, frames and solver; ingest,
# query and session compose them with db/ and io/ (no arrow sideways between
# ingest and query; session sits above both: the one pipeline uses query,
# a foreign avatar is registered through ingest's registrar; the orientation
# drive segments the avatar over vest's skeleton; sampled pose-pairs become
# templates through it, read with sample's joints); serve/ uses
# everything below it; cli/ everything. synth/ (the procedural bodies) uses
# core only. `*` means any module.
TABLE='
core:
io:        core
db:        core
transfer:  core
index:     core
vest:      core
synth:     core
sample:    core
register:  core transfer
query:     core db index
ingest:    core db io transfer register
session:   core db io transfer register index query ingest vest sample
serve:     core db io transfer register index query ingest sample vest synth session
cli:       *
'
# Folders that are no library: nothing of 1. or 2. applies to them.
NOT_LIBRARY='cli tests bench'
# mim_*.h headers that belong to no module: generated from schemas/.
GENERATED_HEADERS='mim_schema_version.h'

# What library code may not call (extended regular expression).
banned='\b(printf|vprintf|puts|putchar|perror|getenv|secure_getenv|setenv|putenv|unsetenv|srand|srandom|srand48|pthread_attr_setstacksize|pthread_setattr_default_np)[[:space:]]*\(|\b(fprintf|vfprintf|fputs|fputc|fwrite|putc)[[:space:]]*\([^;]*\b(stderr|stdout)\b|std::(cout|cerr|clog)\b'
include_re='^[[:space:]]*#[[:space:]]*include[[:space:]]*([<"])([^">]+)[">]'

set -u
root=${1:-$(cd "$(dirname "$0")/.." && pwd)}
cd "$root" || { echo "check_layering: cannot enter $root"; exit 2; }
root=$(pwd -P)

declare -A allowed
modules=()
while IFS= read -r line; do
    [[ $line =~ ^([a-z_]+):(.*)$ ]] || continue
    m=${BASH_REMATCH[1]}
    modules+=("$m")
    read -r -a uses <<<"${BASH_REMATCH[2]}"
    allowed[$m]="${uses[*]}"
done <<<"$TABLE"

n_bad=0
bad() { echo "$1"; n_bad=$((n_bad + 1)); }
in_list() { [[ " $2 " == *" $1 "* ]]; }

# The module a public header belongs to: mim_<module>.h or
# mim_<module>_<part>.h, the longest module name that fits; empty if none.
header_module() {
    local base=${1%.h} best=''
    base=${base#mim_}
    for m in "${modules[@]}"; do
        if [[ $base == "$m" || $base == "$m"_* ]] && ((${#m} > ${#best})); then best=$m; fi
    done
    echo "$best"
}

# The module folders: top-level folders with a CMakeLists.txt.
folders=()
for d in */; do
    d=${d%/}
    [[ -f $d/CMakeLists.txt ]] || continue
    folders+=("$d")
    if [[ -z ${allowed[$d]+x} ]] && ! in_list "$d" "$NOT_LIBRARY"; then
        bad "$d/CMakeLists.txt:1: module $d is not in the layering table of tests/check_layering.sh (DESIGN.md: what may it use?)"
    fi
done

n_files=0 n_modules=0
for d in "${folders[@]}"; do
    in_list "$d" "$NOT_LIBRARY" && continue
    use=${allowed[$d]:-}
    mapfile -t files < <(find "$d" -type f \( -name '*.c' -o -name '*.h' -o -name '*.cpp' -o -name '*.hh' -o -name '*.hpp' \) | sort)
    ((${#files[@]})) || continue
    n_files=$((n_files + ${#files[@]})) n_modules=$((n_modules + 1))

    # 1. what library code may not call
    while IFS= read -r hit; do
        [[ -n $hit ]] || continue
        file=${hit%%:*} rest=${hit#*:}
        lineno=${rest%%:*} code=${rest#*:}
        [[ $code =~ ^[[:space:]]*(//|/\*|\*) ]] && continue
        # leave out comments on the line: /* ... */, then an open /* or //
        code=$(sed -E 's:/\*([^*]|\*+[^*/])*\*+/: :g; s:/\*.*$::; s://.*$::' <<<"$code")
        while IFS= read -r what; do
            what=${what%%[[:space:](]*}
            bad "$file:$lineno: library code calls $what: only cli/ prints, and libraries touch no process-wide state (DESIGN.md)"
        done < <(grep -oE "$banned" <<<"$code")
    done < <(grep -nE "$banned" "${files[@]}" /dev/null)

    # 2. what a module may include
    while IFS= read -r hit; do
        [[ -n $hit ]] || continue
        file=${hit%%:*} rest=${hit#*:}
        lineno=${rest%%:*} code=${rest#*:}
        [[ $code =~ $include_re ]] || continue
        quote=${BASH_REMATCH[1]} inc=${BASH_REMATCH[2]} name=${BASH_REMATCH[2]##*/}
        if [[ $name == mim_*.h ]]; then
            in_list "$name" "$GENERATED_HEADERS" && continue
            m=$(header_module "$name")
            if [[ -z $m ]]; then
                bad "$file:$lineno: includes $inc, the header of no module in the layering table"
            elif [[ $m != "$d" ]] && ! in_list "$m" "$use" && ! in_list '*' "$use"; then
                bad "$file:$lineno: $d/ includes $inc: $d/ may not use $m/ (may use: ${use:-nothing})"
            elif [[ $inc == */* ]]; then
                bad "$file:$lineno: includes $inc by a path: name public headers alone"
            fi
        elif [[ $quote == '"' ]]; then
            # a private header: the module's own, next to the file
            here=$(dirname "$file")
            if [[ -e $here/$inc ]]; then
                real=$(realpath -m "$here/$inc")
                [[ $real == "$root/$d/"* ]] ||
                    bad "$file:$lineno: includes $inc, outside $d/: another module's private header"
            else
                for o in "${folders[@]}"; do
                    if [[ $o != "$d" && -e $o/$inc ]]; then
                        bad "$file:$lineno: includes $inc, a private header of $o/"
                        break
                    fi
                done
            fi
        fi
    done < <(grep -nE '^[[:space:]]*#[[:space:]]*include' "${files[@]}" /dev/null)

    # 2b. what a module links
    if [[ -f $d/CMakeLists.txt ]] && ! in_list '*' "$use"; then
        # the text of each target_link_libraries(mim_<d> ...) call, to its ")"
        while IFS=: read -r lineno dep; do
            [[ $dep == "mim_$d" ]] && continue
            m=${dep#mim_}
            in_list "$m" "$use" ||
                bad "$d/CMakeLists.txt:$lineno: mim_$d links $dep: $d/ may not use $m/ (may use: ${use:-nothing})"
        done < <(awk -v t="mim_$d" '
            /target_link_libraries[[:space:]]*\(/ { on = 0; s = $0; sub(/.*target_link_libraries[[:space:]]*\([[:space:]]*/, "", s)
                split(s, w, /[[:space:]()]+/); if (w[1] == t) on = 1 }
            on { s = $0; sub(/#.*/, "", s); first = (s ~ /target_link_libraries/)
                 n = split(s, w, /[[:space:]()]+/)
                 for (i = 1; i <= n; i++) if (w[i] ~ /^mim_[a-z_]+$/ && !(first && w[i] == t)) print NR ":" w[i]
                 if (s ~ /\)/) on = 0 }' "$d/CMakeLists.txt")
    fi
done

if ((n_bad)); then
    echo "check_layering: $n_bad violation(s)"
    exit 1
fi
echo "check_layering: ok ($n_modules modules, $n_files library files)"
