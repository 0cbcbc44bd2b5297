#!/usr/bin/env bash
# The benchmark's own environment, .venv-peers in the repository root: lightprobe (editable) plus the peers that
# benchmarks/bench_peers.py compares it with, pinned in benchmarks/peers/requirements.txt. Run again: harmless.
set -euo pipefail
cd "$(dirname "$0")/../.."
[ -x .venv-peers/bin/python ] || python3 -m venv .venv-peers
.venv-peers/bin/python -m pip install -q --disable-pip-version-check -e . -r benchmarks/peers/requirements.txt
echo "peers installed: run .venv-peers/bin/python benchmarks/bench_peers.py"
