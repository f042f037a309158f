#!/bin/sh
# CI for the Python package: installs it from this clone into a fresh virtual environment (one
# `pip install`, which builds the C library with CMake) and runs its tests, the wheel test
# included (tests/test_wheel.py: `python -m build` makes the sdist and, from it alone, the
# wheel, which it installs into a second fresh environment). Called by .ci/run after the C workflows; needs python3-venv and PyPI.
set -eu
cd "$(dirname "$0")"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
export CMAKE_BUILD_PARALLEL_LEVEL="${CMAKE_BUILD_PARALLEL_LEVEL:-2}"
export PIP_DISABLE_PIP_VERSION_CHECK=1
python3 -m venv "$work/venv"
# scipy and ase: the neighbour lists are checked against cKDTree and ASE's neighbour list
"$work/venv/bin/python" -m pip install -q pytest scikit-build-core build scipy ase
"$work/venv/bin/python" -m pip install -q .
"$work/venv/bin/python" -m pytest -q -p no:cacheprovider tests
