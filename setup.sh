#!/usr/bin/env bash
# Set up .venv in the repository root with everything lightprobe needs; running it again is harmless.
#   bash setup.sh          the package and its runtime dependencies
#   bash setup.sh --test   plus the test and reference-rendering dependencies
# Installs Debian packages with apt-get when something needed is missing (as root, or through sudo).
set -euo pipefail
cd "$(dirname "$0")"

extras=""
[ "${1:-}" = "--test" ] && extras="[test]"

python3 -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' || {
  echo "setup.sh: lightprobe needs Python 3.11 or newer as python3" >&2; exit 2; }

apt_packages=()
python3 -c 'import venv, ensurepip' 2>/dev/null || apt_packages+=(python3-venv)
if [ ${#apt_packages[@]} -gt 0 ]; then
  sudo=""; [ "$(id -u)" = 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${apt_packages[@]}"
fi

[ -x .venv/bin/python ] || python3 -m venv .venv

# Reinstall only when the requirements changed since the last run.
stamp=".venv/.lightprobe-setup"
want="$(sha256sum pyproject.toml | cut -c1-16)${extras}"
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ] || ! .venv/bin/python -c 'import lightprobe' 2>/dev/null; then
  .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
  .venv/bin/python -m pip install -q --disable-pip-version-check -e ".${extras}"
  echo "$want" > "$stamp"
fi
