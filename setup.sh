#!/usr/bin/env bash
# Set up .venv in the repository root with everything lightprobe needs; running it again is harmless.
#   bash setup.sh          the package with the Mitsuba 3 reference renderer (the demo shows its ground truth) and the
#                          engines the exports are shown in (Debian's chromium + Playwright, Node with the npm
#                          packages pinned in engines/package-lock.json)
#   bash setup.sh --test   plus the test dependencies (the engines are required then, not best-effort)
# Both try Debian's libllvm19 for Mitsuba's fast LLVM variant (without it the reference uses the slower scalar one).
# Installs Debian packages with apt-get when something needed is missing (as root, or through sudo).
set -euo pipefail
cd "$(dirname "$0")"

extras="[reference,engines,dask]"
testing=""
[ "${1:-}" = "--test" ] && extras="[test,reference,engines,dask]" && testing=1

python3 -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' || {
  echo "setup.sh: lightprobe needs Python 3.11 or newer as python3" >&2; exit 2; }

sudo=""; [ "$(id -u)" = 0 ] || sudo="sudo"
apt_install() {  # apt_install required|optional PACKAGE...
  local need=$1; shift
  [ $# -gt 0 ] || return 0
  if ! command -v apt-get >/dev/null; then
    [ "$need" = optional ] && return 0
    echo "setup.sh: please install $* (no apt-get here)" >&2; exit 2
  fi
  if ! { $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "$@"; }; then
    [ "$need" = optional ] || { echo "setup.sh: could not install $*" >&2; exit 2; }
    echo "setup.sh: optional $* not installed; continuing" >&2
  fi
}

required=()
python3 -c 'import venv, ensurepip' 2>/dev/null || required+=(python3-venv)
apt_install required "${required[@]}"
engines=()  # three.js runs in Debian's Chromium (Playwright drives it), Babylon.js in Node
[ -x /usr/bin/chromium ] || engines+=(chromium)
command -v node >/dev/null || engines+=(nodejs)
command -v npm >/dev/null || engines+=(npm)
apt_install "$([ -n "$testing" ] && echo required || echo optional)" "${engines[@]}"
if ! ls /usr/lib/*/libLLVM-19.so* /usr/lib/llvm-19/lib/libLLVM* >/dev/null 2>&1; then
  apt_install optional libllvm19  # Mitsuba's fast LLVM variant; the reference falls back to scalar_rgb without it
fi

[ -x .venv/bin/python ] || python3 -m venv .venv

# Reinstall only when the requirements changed since the last run.
stamp=".venv/.lightprobe-setup"
want="$(sha256sum pyproject.toml | cut -c1-16)${extras}"
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ] || ! .venv/bin/python -c 'import lightprobe' 2>/dev/null; then
  .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
  .venv/bin/python -m pip install -q --disable-pip-version-check -e ".${extras}"
  # Bytecode for everything installed, even where PYTHONDONTWRITEBYTECODE is set: otherwise every command compiles
  # numba, numpy and lightprobe from source at each start (~0.3 s and ~65 MiB more at its peak).
  .venv/bin/python -m compileall -q -j 0 .venv/lib src >/dev/null || true
  echo "$want" > "$stamp"
fi

# The engines the exports are checked in, pinned by engines/package-lock.json (never copied into the repository).
lock="engines/node_modules/.lightprobe-lock"
if command -v npm >/dev/null && [ "$(cat "$lock" 2>/dev/null)" != "$(sha256sum engines/package-lock.json | cut -c1-16)" ]; then
  if (cd engines && npm ci --no-audit --no-fund --loglevel=error >/dev/null); then
    sha256sum engines/package-lock.json | cut -c1-16 > "$lock"
  elif [ -n "$testing" ]; then
    echo "setup.sh: npm ci in engines/ failed" >&2; exit 2
  else
    echo "setup.sh: the engines (npm ci in engines/) are not installed; the demo will say so" >&2
  fi
fi

# Compile lightprobe's numba kernels here, once, rather than in the first command (three to four minutes on 2 cores; the
# demo's own run is then warm). Again only when the sources changed or numba's cache folder is gone.
stamp=".venv/.lightprobe-kernels"
sources="$(cat src/lightprobe/*.py src/lightprobe/*/*.py | sha256sum | cut -c1-16)"
cache="${NUMBA_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/lightprobe/numba}"
if [ "$(cat "$stamp" 2>/dev/null)" != "$sources" ] || [ ! -d "$cache" ]; then
  LIGHTPROBE_PROGRESS=0 .venv/bin/python -m lightprobe.warmup || {
    echo "setup.sh: compiling lightprobe's kernels failed" >&2; exit 2; }
  echo "$sources" > "$stamp"
fi
