#!/usr/bin/env bash
# The main job on its embedded default: the model workbench on the flying platform's 18
# closed-loop identification experiments (generated deterministically, with momentum drag and
# fan gyroscopic torque hidden in the truth): compare, diagnose, discover the missing effects,
# write out/discover.json and the report out/report/index.html.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
mkdir -p out
cargo run --release -q -p sim --bin stabilis -- discover --report out/report --json out/discover.json
