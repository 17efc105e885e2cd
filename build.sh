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
  libhidapi-dev libcivetweb-dev
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
  # npm packages (package.json: the Khronos glTF validator and playwright-core
  # for the tests, three.js, which the build embeds into the web viewer),
  # installed exactly as package-lock.json pins them, when node_modules is
  # missing or older than the lock file. Without npm those tests skip and the
  # viewer says three.js is missing.
  if command -v npm >/dev/null 2>&1; then
    if [ ! -f node_modules/.package-lock.json ] || [ package-lock.json -nt node_modules/.package-lock.json ]; then
      echo "build.sh: npm ci (package-lock.json)" >&2
      npm ci --no-audit --no-fund --loglevel=error >&2
    fi
  else
    echo "build.sh: npm not found: the glTF validator and viewer tests will be skipped, the viewer has no three.js" >&2
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
  echo "== mimic index: pose recognition (angle descriptor, per-class SVMs, FLANN)"
  "$mimic" index --store "$out/store"
  # ids follow file order: subject s, pose p is template 1 + 12 s + p
  echo "== mimic transfer: subject 0 at rest into the pose of template 18 (subject 1, pose 5)"
  "$mimic" transfer --store "$out/store" --avatar 1 --template 18 -o "$out/transfer.glb"
  echo "== mimic morph: subject 0 through the poses of templates 14, 17 and 21, 8 frames between keys"
  "$mimic" morph --store "$out/store" --avatar 1 --keys 14,17,21 --frames-between 8 -o "$out/morph.glb"
  echo "== wrote $out/transfer.glb and $out/morph.glb (open them in any glTF viewer)"
}

cmd=${1:-}
case "$cmd" in
  demo)  install_deps; configure_build build; demo ;;
  build) install_deps; configure_build build ;;
  test)
    # the browser test of the web viewer (tests/viewer_test.mjs); big, so
    # only for the tests
    TEST_PACKAGES=(chromium)
    PACKAGES+=("${TEST_PACKAGES[@]}")
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
