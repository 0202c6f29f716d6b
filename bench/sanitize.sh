#!/usr/bin/env bash
# Builds the C++ tests twice with sanitizers and runs them:
#   BUILD_ROOT/asan  AddressSanitizer + UndefinedBehaviorSanitizer, every test;
#   BUILD_ROOT/tsan  ThreadSanitizer, every test except the timing-sensitive
#                    ones (ctest names matching TSAN_EXCLUDE below; tests also
#                    see WIRETAPE_TSAN=1 and may skip themselves).
# clang-14 is used when present, else the default C++ compiler (gcc).
# Usage: bench/sanitize.sh BUILD_ROOT [asan|tsan]...
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build_root=${1:?usage: sanitize.sh BUILD_ROOT [asan|tsan]...}
shift
kinds=("$@")
[ ${#kinds[@]} -eq 0 ] && kinds=(asan tsan)

if command -v clang++-14 >/dev/null 2>&1; then
  cxx=clang++-14
else
  cxx=${CXX:-c++}
  echo "sanitize: clang++-14 not found, using $cxx"
fi
jobs=${JOBS:-2}
# Timing-sensitive tests (their names say so) are not run under TSan: its
# 5-15x slowdown makes their loose bounds meaningless.
TSAN_EXCLUDE='[Tt]iming|[Ll]atency|[Tt]hroughput|[Dd]rift|[Ss]oak|consumer_find_package'

configure_and_build() {  # dir sanitizers [command prefix]
  local dir=$1 sanitizers=$2
  shift 2
  cmake -S "$root" -B "$dir" -G Ninja -DCMAKE_CXX_COMPILER="$cxx" \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWIRETAPE_SANITIZE="$sanitizers" \
    -DWIRETAPE_PYTHON=OFF -DWIRETAPE_TESTS=ON -DWIRETAPE_EXAMPLES=ON \
    -DWIRETAPE_FUZZ=OFF -DWIRETAPE_BENCH=OFF -DWIRETAPE_INSTALL=OFF >/dev/null
  # The build runs the test programs to list their tests: same prefix.
  "$@" cmake --build "$dir" -j "$jobs"
}

# Linux >= 6.5 randomises mmap bases more than clang-14's TSan accepts
# ("unexpected memory mapping"); running without ASLR avoids it.
no_aslr=()
if setarch "$(uname -m)" -R true 2>/dev/null; then
  no_aslr=(setarch "$(uname -m)" -R)
fi

status=0
for kind in "${kinds[@]}"; do
  case "$kind" in
    asan)
      configure_and_build "$build_root/asan" "address,undefined"
      (cd "$build_root/asan" &&
        ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1 \
        UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
        ctest --output-on-failure -j "$jobs" --timeout 600 -E consumer_find_package) || status=1
      ;;
    tsan)
      configure_and_build "$build_root/tsan" "thread" "${no_aslr[@]}"
      (cd "$build_root/tsan" &&
        WIRETAPE_TSAN=1 TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1 \
        "${no_aslr[@]}" ctest --output-on-failure -j "$jobs" --timeout 600 -E "$TSAN_EXCLUDE") || status=1
      ;;
    *) echo "sanitize: unknown kind $kind (asan|tsan)" >&2; exit 2 ;;
  esac
done
exit $status
