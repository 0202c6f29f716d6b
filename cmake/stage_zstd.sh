#!/usr/bin/env bash
# Stages the host's libzstd (Debian's libzstd-dev) as a prefix of its own for
# the wheels' zig build: its CMake config, headers and libraries mirrored
# under PREFIX. Pointed at /usr directly, the config's include directory
# would put all of /usr/include before zig's glibc 2.28 headers.
# Usage: cmake/stage_zstd.sh PREFIX
set -euo pipefail
prefix=$1
config=$(ls /usr/lib/*/cmake/zstd/zstdConfig.cmake 2>/dev/null | head -n 1) || true
if [ -z "$config" ]; then
  echo "stage_zstd: no zstd CMake config under /usr/lib/*/cmake/zstd (apt-get install libzstd-dev)" >&2
  exit 1
fi
libdir=$(dirname "$(dirname "$(dirname "$config")")")   # /usr/lib/<arch>
relative=${libdir#/usr/}                                  # lib/<arch>
rm -rf "$prefix"
mkdir -p "$prefix/include" "$prefix/$relative/cmake"
cp /usr/include/zstd.h /usr/include/zstd_errors.h /usr/include/zdict.h "$prefix/include/"
cp -a "$libdir"/libzstd.* "$prefix/$relative/"
cp -r "$(dirname "$config")" "$prefix/$relative/cmake/"
