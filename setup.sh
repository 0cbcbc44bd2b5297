#!/usr/bin/env bash
# Set up .venv in the repository root with everything lightprobe needs; running it again is harmless.
#   bash setup.sh          the package with every extra (render, reference: Mitsuba 3, batch, viewer), the viewer's
#                          three.js modules copied into the package from the npm version engines/ pins, and the
#                          engines harness (engines/lightprobe_engines: Debian's chromium + Playwright, Node with the
#                          npm packages pinned in engines/package-lock.json) the demo shows the exports in
#   bash setup.sh --test   plus the test and docs dependencies (the engines are required then, not best-effort)
# Both try Debian's libllvm19 for Mitsuba's fast LLVM variant (without it the reference uses the slower scalar one).
# Installs Debian packages with apt-get when something needed is missing (as root, or through sudo).
set -euo pipefail
cd "$(dirname "$0")"

extras="[all]"
testing=""
[ "${1:-}" = "--test" ] && extras="[test]" && testing=1

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

# The engines the exports are checked in, pinned by engines/package-lock.json (never copied into the repository).
lock="engines/node_modules/.lightprobe-lock"
engines_ok=""
if command -v npm >/dev/null; then
  if [ "$(cat "$lock" 2>/dev/null)" = "$(sha256sum engines/package-lock.json | cut -c1-16)" ]; then
    engines_ok=1
  elif (cd engines && npm ci --no-audit --no-fund --loglevel=error >/dev/null); then
    sha256sum engines/package-lock.json | cut -c1-16 > "$lock"
    engines_ok=1
  elif [ -n "$testing" ]; then
    echo "setup.sh: npm ci in engines/ failed" >&2; exit 2
  else
    echo "setup.sh: the engines (npm ci in engines/) are not installed; the demo will say so" >&2
  fi
fi
# The viewer's three.js modules inside the package, as the wheel carries them (engines/vendor_three.py).
if [ -n "$engines_ok" ]; then
  python3 engines/vendor_three.py src/lightprobe/viewer/vendor/three >/dev/null
fi

# Reinstall only when the requirements changed since the last run.
stamp=".venv/.lightprobe-setup"
want="$(cat pyproject.toml engines/pyproject.toml | sha256sum | cut -c1-16)${extras}${engines_ok}"
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ] || ! .venv/bin/python -c 'import lightprobe' 2>/dev/null; then
  .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
  .venv/bin/python -m pip install -q --disable-pip-version-check -e ".${extras}"
  if [ -n "$engines_ok" ]; then  # the development harness the demo and the tests drive the engines with
    .venv/bin/python -m pip install -q --disable-pip-version-check -e engines
  fi
  # Bytecode for everything installed, even where PYTHONDONTWRITEBYTECODE is set: otherwise every command compiles
  # numba, numpy and lightprobe from source at each start (~0.3 s and ~65 MiB more at its peak).
  .venv/bin/python -m compileall -q -j 0 .venv/lib src >/dev/null || true
  echo "$want" > "$stamp"
fi

# Compile lightprobe's numba kernels here, once, rather than in the first command (about two minutes on 2 cores; the
# demo's own run is then warm). Again only when the kernels' sources changed: lightprobe keys numba's cache folder by
# them, and the warm-up marks a folder it completed.
cache="$(.venv/bin/python -c 'import os, lightprobe; print(os.environ["NUMBA_CACHE_DIR"])')"
if [ ! -f "$cache/.lightprobe-warm" ]; then
  LIGHTPROBE_PROGRESS=0 .venv/bin/python -m lightprobe.warmup || {
    echo "setup.sh: compiling lightprobe's kernels failed" >&2; exit 2; }
fi
