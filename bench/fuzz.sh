#!/usr/bin/env bash
# Runs every libFuzzer target (fuzz/*_fuzz.cpp) for SECONDS each, starting
# from its seed corpus in fuzz/corpus/<name>/ (never modified: new inputs go
# to BUILD_DIR/corpus/<name>/). Crashes are written to BUILD_DIR/artifacts/.
# Usage: bench/fuzz.sh BUILD_DIR SECONDS
set -euo pipefail
build=${1:?usage: fuzz.sh BUILD_DIR SECONDS}
seconds=${2:?usage: fuzz.sh BUILD_DIR SECONDS}
root="$(cd "$(dirname "$0")/.." && pwd)"
shopt -s nullglob
sources=("$root"/fuzz/*_fuzz.cpp)
if [ ${#sources[@]} -eq 0 ]; then
  echo "fuzz: no fuzz/*_fuzz.cpp targets yet; nothing to run"
  exit 0
fi
mkdir -p "$build/artifacts"
failed=()
for source in "${sources[@]}"; do
  name=$(basename "$source" .cpp)
  program=$(find "$build" -type f -perm -u+x -name "$name" | head -n 1)
  if [ -z "$program" ]; then
    echo "fuzz: $name was not built (see $build); failing" >&2
    failed+=("$name")
    continue
  fi
  help=$("$program" -help=1 2>&1 || true)
  if [[ "$help" != *libFuzzer* ]]; then
    echo "fuzz: $program is not a libFuzzer program (built without clang?); failing" >&2
    failed+=("$name")
    continue
  fi
  mkdir -p "$build/corpus/$name"
  seeds=()
  [ -d "$root/fuzz/corpus/$name" ] && seeds+=("$root/fuzz/corpus/$name")
  echo "fuzz: $name for ${seconds}s"
  if ! "$program" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
      -print_final_stats=1 -artifact_prefix="$build/artifacts/$name-" \
      "$build/corpus/$name" "${seeds[@]}" >"$build/$name.log" 2>&1; then
    echo "fuzz: $name FAILED; the last lines of $build/$name.log:" >&2
    tail -n 40 "$build/$name.log" >&2
    failed+=("$name")
  else
    grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$build/$name.log" | sed "s/^/  /"
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: failed: ${failed[*]}" >&2
  exit 1
fi
echo "fuzz: all targets ran clean"
