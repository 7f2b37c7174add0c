#!/usr/bin/env bash
# Write the OpenVDB fixtures of tests/it/vdb.rs with OpenVDB itself (Debian bookworm: OpenVDB 10.0.1,
# file format 224) and their truth: what OpenVDB returns when it reads each file back.
# Re-runnable; CI does not run it (it reads the committed files). Run from anywhere:
#     bash validation/vdb/make_fixtures.sh            # fixtures into tests/fixtures/vdb/
#     BENCH=1 bash validation/vdb/make_fixtures.sh    # also /tmp/ohd-vdb-bench/dense_{128,256}.vdb
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
out="$repo/tests/fixtures/vdb"
work="$(mktemp -d /tmp/ohd-vdb-fixtures.XXXXXX)"
trap 'rm -rf "$work"' EXIT

need=()
/usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null || need+=(python3-openvdb)
command -v vdb_print >/dev/null || need+=(libopenvdb-tools)
[ -f /usr/include/openvdb/openvdb.h ] || need+=(libopenvdb-dev)
[ -d /usr/include/boost ] || need+=(libboost-dev)
command -v g++ >/dev/null || need+=(g++)
if [ ${#need[@]} -gt 0 ]; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}"
fi

py=/usr/bin/python3   # Debian's python3-openvdb is built for the system interpreter
g++ -O1 -std=c++17 -o "$work/vdbfix" "$here/vdbfix.cpp" -lopenvdb -ltbb -lImath-3_1
"$py" "$here/scene.py" build "$work"
"$work/vdbfix" maps "$work/transforms.vdb"

mkdir -p "$out"
rm -f "$out"/*.vdb "$out"/*.truth.gz
# name  compression flags (io/Compression.h: 1 zip, 2 active mask, 4 blosc)  half
encodings="none 0 0
zip 1 0
active 2 0
zip_active 3 0
blosc 4 0
blosc_active 6 0
half_zip 1 1
half_zip_active 3 1
half_blosc 4 1
half_blosc_active 6 1"
while read -r name flags half; do
    "$work/vdbfix" recode "$work/scene.vdb" "$out/scene_$name.vdb" "$flags" "$half"
done <<< "$encodings"
cp "$work/extra.vdb" "$out/extra.vdb"                      # pyopenvdb's default codec
"$work/vdbfix" recode "$work/extra.vdb" "$out/extra_half.vdb" 6 1
cp "$work/root_tile.vdb" "$out/root_tile.vdb"
cp "$work/transforms.vdb" "$out/transforms.vdb"

# Truth: one file per group of fixtures that must read identically; check that OpenVDB reads
# every member of a group the same (a mismatch would be a fixture bug, not a reader bug).
"$py" "$here/scene.py" truth "$out/scene_none.vdb" "$out/scene.truth.gz"
"$py" "$here/scene.py" truth "$out/scene_half_zip.vdb" "$out/scene_half.truth.gz"
while read -r name flags half; do
    "$py" "$here/scene.py" truth "$out/scene_$name.vdb" "$work/check.gz"
    ref="$out/scene.truth.gz"; [ "$half" = 1 ] && ref="$out/scene_half.truth.gz"
    cmp -s <(zcat "$work/check.gz") <(zcat "$ref") || { echo "OpenVDB reads scene_$name differently" >&2; exit 1; }
done <<< "$encodings"
for f in extra extra_half root_tile; do
    "$py" "$here/scene.py" truth "$out/$f.vdb" "$out/$f.truth.gz"
done
"$py" "$here/scene.py" truth "$out/transforms.vdb" "$out/transforms.truth.gz" light
# The compression each grid was really stored with (OpenVDB drops zip for fog volumes).
for f in "$out"/*.vdb; do
    printf '%s: ' "$(basename "$f")"; vdb_print -l "$f" | grep file_compression | sort -u | tr -s ' ' | tr '\n' ';'; echo
done
du -ch "$out" | tail -1

if [ "${BENCH:-0}" = 1 ]; then
    mkdir -p /tmp/ohd-vdb-bench
    for n in 128 256; do "$py" "$here/scene.py" bench "/tmp/ohd-vdb-bench/dense_$n.vdb" "$n"; done
    ls -la /tmp/ohd-vdb-bench
fi
