#!/usr/bin/env bash
# The main job on its embedded default: simulate the balancing reaction-wheel pendulum,
# write out/run.mcap and summarise it.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p out
cargo run --release -q -p sim --bin stabilis -- sim wheel-pendulum --duration 10 --out out/run.mcap
cargo run --release -q -p sim --bin stabilis -- info out/run.mcap
