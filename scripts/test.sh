#!/usr/bin/env bash
# Runs every check of stabilis: formatting, lints, Rust tests, the no_std builds,
# benchmark compilation, the Python wheel and its tests. `--campaigns` adds the further seeds of
# the studies that take a minute or more per seed (pytest's `campaign` mark, STABILIS_CAMPAIGNS).
set -euo pipefail
cd "$(dirname "$0")/.."
campaigns=false
case "${1:-}" in
    "") ;;
    --campaigns) campaigns=true ;;
    *) echo "usage: scripts/test.sh [--campaigns]" >&2; exit 2 ;;
esac
# The Rust studies read the choice from STABILIS_CAMPAIGNS (their further seeds).
$campaigns && export STABILIS_CAMPAIGNS=1
scripts/setup.sh

step() { echo; echo "== $*"; }

step "cargo fmt"
cargo fmt --all --check
step "cargo clippy"
cargo clippy --workspace --all-targets --release -- -D warnings
step "cargo test"
cargo test --workspace --release
step "no_std builds"
for crate in rigid_body tilt cubli event_est; do
    cargo build --release -p "$crate" --no-default-features --features libm
done
step "benchmarks compile"
cargo bench --workspace --no-run
step "Python wheel"
rm -rf target/wheels target/pytest-site
.venv/bin/maturin build --release -q -m py/Cargo.toml -o target/wheels
# Installed into its own directory, put first on the path, so that the tests see this wheel even
# if .venv holds an editable (maturin develop) install.
.venv/bin/python -m pip install -q --no-deps --target target/pytest-site target/wheels/stabilis-*.whl
step "pytest"
# From py/, where `stabilis` is not importable from source: the tests use the installed wheel and
# the release binary (the interop tests run `stabilis info`).
cargo build --release -q -p sim --bin stabilis
export STABILIS_BIN="$PWD/target/release/stabilis"
site="$PWD/target/pytest-site"
# Two workers; a worker that runs out of tests takes some of the other's.
select=(-m "not campaign")
$campaigns && select=()
(cd py && PYTHONPATH="$site" ../.venv/bin/python -m pytest -q -n 2 --dist worksteal "${select[@]}" tests)
