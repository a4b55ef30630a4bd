#!/usr/bin/env bash
# Quick-start command 2: install what is missing, build, run the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
CUTLOAD_EXTRA_PACKAGES="chromium ${CUTLOAD_EXTRA_PACKAGES:-}" scripts/setup.sh
BUILD_DIR=${CUTLOAD_BUILD_DIR:-build}
cd "$BUILD_DIR"
ctest --output-on-failure -j "${CUTLOAD_JOBS:-$(nproc)}"
