#!/usr/bin/env bash
# Regenerate media/vdb/*.vdb with OpenVDB itself (Debian's python3-openvdb 10).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
if ! /usr/bin/python3 -c "import pyopenvdb" 2>/dev/null; then
    apt-get update -qq && apt-get install -y -qq python3-openvdb
fi
/usr/bin/python3 "$here/make_assets.py" "$here"
