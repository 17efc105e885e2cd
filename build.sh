#!/usr/bin/env bash
# mimic's one entry point for a fresh Debian 12 machine.
#   ./build.sh demo   install what is missing, build, run the demo
#   ./build.sh test   install what is missing, build, run the whole test suite
#                     (a -Werror build, then an ASan+UBSan build)
#   ./build.sh build  install what is missing and build (build/cli/mimic)
#   ./build.sh fuzz [SECONDS]  libFuzzer harnesses (clang), each for SECONDS (default 60)
set -euo pipefail
cd "$(dirname "$0")"

# Debian packages mimic builds and tests with (DESIGN.md, "Dependencies").
PACKAGES=(
  build-essential cmake pkg-config
  libopenmesh-dev libtinygltf-dev
  liblmdb-dev libjansson-dev libcmocka-dev
  libsuitesparse-dev libopenblas-dev libflann-dev libsvm-dev
  python3-jsonschema
)

install_deps() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "build.sh: installing ${missing[*]}" >&2
    local sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  fi
}

configure_build() { # dir, extra cmake args...; the compiler's output is shown only on failure
  local dir=$1; shift
  echo "build.sh: building in $dir" >&2
  mkdir -p "$dir"
  if ! { cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@" && cmake --build "$dir" -j"$(nproc)"; } > "$dir/build.log" 2>&1; then
    cat "$dir/build.log" >&2
    echo "build.sh: build failed in $dir (log: $dir/build.log)" >&2
    exit 1
  fi
}

run_tests() { # dir
  (cd "$1" && ctest --output-on-failure -j"$(nproc)")
}

demo() {
  local out=build/demo mimic=build/cli/mimic
  rm -rf "$out"
  mkdir -p "$out"
  echo "== mimic synth: 4 subjects x 12 poses of synthetic bodies"
  "$mimic" synth --out "$out/bodies" --subjects 4 --poses 12
  echo "== mimic ingest: into the template store $out/store"
  "$mimic" ingest --store "$out/store" "$out/bodies"
  echo "== mimic info"
  "$mimic" info --store "$out/store"
}

cmd=${1:-}
case "$cmd" in
  demo)  install_deps; configure_build build; demo ;;
  build) install_deps; configure_build build ;;
  test)
    install_deps
    configure_build build -DMIM_WERROR=ON
    run_tests build
    configure_build build-asan -DMIM_WERROR=ON -DMIM_SANITIZE=ON -DCMAKE_BUILD_TYPE=Debug
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 run_tests build-asan
    ;;
  fuzz)
    PACKAGES+=(clang libclang-rt-14-dev)
    install_deps
    CC=clang CXX=clang++ configure_build build-fuzz -DMIM_FUZZ=ON -DMIM_SANITIZE=ON -DCMAKE_BUILD_TYPE=Debug
    for f in build-fuzz/tests/fuzz_*; do
      name=$(basename "$f")
      mkdir -p "build-fuzz/corpus/$name"
      cp -n tests/fuzz/seeds/"$name"/* "build-fuzz/corpus/$name/" 2>/dev/null || true
      "$f" -max_total_time="${2:-60}" -timeout=10 -rss_limit_mb=4096 -max_len=65536 "build-fuzz/corpus/$name"
    done
    ;;
  *) echo "usage: ./build.sh demo|test|build|fuzz [SECONDS]" >&2; exit 2 ;;
esac
