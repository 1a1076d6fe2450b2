#!/usr/bin/env bash
# The main job: set up, build, and replay a bundled recording.
#   bash scripts/demo.sh [RECORDING] [OUT]
set -euo pipefail
cd "$(dirname "$0")/.."
rec="${1:-recordings/box_small}"
out="${2:-results/$(basename "$rec")}"
bash scripts/setup.sh
bash scripts/build.sh
./build/tagsfm replay "$rec" --out "$out"
