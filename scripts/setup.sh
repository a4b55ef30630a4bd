#!/usr/bin/env bash
# Installs the Debian 12 packages cutload needs (only those missing) and builds it into build/.
# Safe to run again: apt and cmake only do what is left to do.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake pkg-config git ca-certificates
  libeigen3-dev opencl-headers ocl-icd-opencl-dev pocl-opencl-icd clinfo
  nlohmann-json3-dev libcpp-httplib-dev libsqlite3-dev sqlite3 catch2
  libcli11-dev libspdlog-dev libfmt-dev libpugixml-dev
  curl
  # The PostgreSQL store (docs/deploy.md): libpq to build against; the server binaries (Debian
  # keeps them in /usr/lib/postgresql/15/bin) for the throw-away cluster the server-pg tests start.
  libpq-dev postgresql
  # The fuzz test (scripts/fuzz.sh, docs/fuzzing.md): clang and its runtime libraries (libFuzzer,
  # the address and undefined-behaviour sanitizers). Without them that one test is skipped.
  clang libclang-rt-dev
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# The web page is built with npm. Judge by the command, not the package: a machine may carry a
# newer Node.js from elsewhere whose bundled npm conflicts with Debian's npm package.
command -v npm >/dev/null 2>&1 || missing+=(nodejs npm)
if command -v node >/dev/null 2>&1; then
  node_major=$(node -p 'process.versions.node.split(".")[0]' 2>/dev/null || echo 0)
  if [ "$node_major" -lt 18 ]; then
    echo "cutload setup: Node.js $(node --version) is too old for the web build (need 18 or newer)" >&2
    exit 1
  fi
fi
# Extra packages asked for by the caller (scripts/test.sh adds the browser for the web tests).
for p in ${CUTLOAD_EXTRA_PACKAGES:-}; do
  case "$p" in
    chromium) [ -x /usr/bin/chromium ] || missing+=(chromium) ;;
    *) dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p") ;;
  esac
done
if ((${#missing[@]})); then
  echo "cutload setup: installing ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

BUILD_DIR=${CUTLOAD_BUILD_DIR:-build}
JOBS=${CUTLOAD_JOBS:-$(nproc)}
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >/dev/null
# CUTLOAD_TARGETS narrows the build (scripts/start.sh needs only the executable and the page).
if [ -n "${CUTLOAD_TARGETS:-}" ]; then
  # shellcheck disable=SC2086
  cmake --build "$BUILD_DIR" -j "$JOBS" --target $CUTLOAD_TARGETS
else
  cmake --build "$BUILD_DIR" -j "$JOBS"
fi
