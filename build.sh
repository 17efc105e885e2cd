#!/usr/bin/env bash
# mimic's one entry point for a fresh Debian 12 machine.
#   ./build.sh demo   install what is missing, build, run the demo (mimic demo, 10 s, headless)
#   ./build.sh test   install what is missing, build, run the whole test suite
#                     (a -Werror build, a -Werror Release build, then an
#                     ASan+UBSan build and the suite again)
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
  libhidapi-dev libwebsockets-dev libxxhash-dev
  liblapacke-dev libssl-dev libqhull-dev libode-dev
  python3-jsonschema
  # issue 16: HAProxy for the deployment test (tests/test_deploy.c), FAISS
  # for bench_knn_compare (neither is linked into mimic)
  haproxy libfaiss-dev
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

demo() { # mimic demo for DEMO_SECONDS (default 10), then the Khronos validator on its GLB
  local out=build/demo mimic=build/cli/mimic
  rm -rf "$out" # the build's own folder (an older demo's layout had no marker)
  "$mimic" demo --dir "$out" --headless --duration "${DEMO_SECONDS:-10}" --listen 127.0.0.1:0
  if command -v node >/dev/null 2>&1 && [ -d node_modules/gltf-validator ]; then
    node tests/gltf_validate.mjs --strict "$out/demo.glb"
  fi
  echo "== to watch it live: $mimic demo   (then open the URL it prints; Ctrl-C stops)"
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
    # a user's -DCMAKE_BUILD_TYPE=Release must build too, warning-free
    # (-O3 finds warnings -O2 does not); its tests are the ones above
    configure_build build-release -DMIM_WERROR=ON -DCMAKE_BUILD_TYPE=Release
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
