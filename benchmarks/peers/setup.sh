#!/usr/bin/env bash
# The benchmark's own environment, .venv-peers in the repository root: lightprobe (editable) plus the peers that
# benchmarks/bench_peers.py and bench_prefilter_peers.py compare it with, pinned in benchmarks/peers/requirements.txt,
# the engines harness (engines/: Playwright driving Debian's Chromium, three.js and Babylon.js from npm) and a Vulkan
# driver for glTF-IBL-Sampler: Mesa's (Debian's mesa-vulkan-drivers: the GPU's driver where there is a GPU, lavapipe
# on the CPU where there is none). Run again: harmless.
set -euo pipefail
cd "$(dirname "$0")/../.."
sudo=""; [ "$(id -u)" = 0 ] || sudo="sudo"
missing=()
[ -e /usr/share/vulkan/icd.d/lvp_icd.x86_64.json ] || ls /usr/share/vulkan/icd.d/*.json >/dev/null 2>&1 \
  || missing+=(mesa-vulkan-drivers)
[ -x /usr/bin/chromium ] || missing+=(chromium)
command -v npm >/dev/null || missing+=(nodejs npm)
if [ ${#missing[@]} -gt 0 ]; then
  $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}"
fi
(cd engines && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
[ -x .venv-peers/bin/python ] || python3 -m venv .venv-peers
.venv-peers/bin/python -m pip install -q --disable-pip-version-check -e . -e engines -r benchmarks/peers/requirements.txt
echo "peers installed: run .venv-peers/bin/python benchmarks/bench_peers.py (or bench_prefilter_peers.py)"
