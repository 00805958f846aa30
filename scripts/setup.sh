#!/usr/bin/env bash
# Installs what stabilis needs on a fresh Debian machine that has Rust and Python:
# the system OpenBLAS (Clarabel's SDP solver links it) and a Python virtual environment
# in .venv with the build and test dependencies. Safe to run again: it skips what is there.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
# chromium: the headless browser that renders the HTML report in py/tests/test_report_browser.py.
for pkg in libopenblas-dev libgfortran-12-dev pkg-config chromium; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need_apt+=("$pkg")
done
# Debian's python3 ships venv (ensurepip) separately.
python3 -c "import ensurepip" >/dev/null 2>&1 || need_apt+=(python3-venv)
if ((${#need_apt[@]})); then
    echo "setup: installing system packages: ${need_apt[*]}"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

# fmt and clippy are rustup components that a minimal Rust install may lack.
if command -v rustup >/dev/null 2>&1 && ! (cargo fmt --version && cargo clippy --version) >/dev/null 2>&1; then
    echo "setup: adding rustfmt and clippy"
    rustup component add rustfmt clippy
fi

if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv"
    python3 -m venv .venv
fi
stamp=.venv/.stabilis-deps
deps="maturin>=1.9.4,<2 pytest pytest-xdist numpy scipy mcap control dask[distributed]"
# Versions pinned by a constraints file: an unpinned install changed numpy/scipy under the
# tests between two machines (see the file's header).
constraints=scripts/python-constraints.txt
want="$deps $(sha256sum "$constraints" | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    echo "setup: installing Python dependencies into .venv"
    .venv/bin/python -m pip install -q --upgrade -c "$constraints" pip
    # Split on spaces, never globbed (dask[distributed] is a bracket pattern to the shell).
    # shellcheck disable=SC2086
    (set -f; .venv/bin/python -m pip install -q -c "$constraints" $deps)
    echo "$want" > "$stamp"
fi
