#!/usr/bin/env bash
# One-command set-up on a fresh Debian machine: LLVM 19 for Mitsuba's LLVM variants, a Python 3.11
# virtual environment in .venv, and renderlab installed into it (editable) with all its extras and the tests, at the
# versions of requirements.lock.
set -euo pipefail
cd "$(dirname "$0")"

if ! ldconfig -p 2>/dev/null | grep -q 'libLLVM.so.19\|libLLVM-19'; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "setup: installing Debian's libllvm19 (Mitsuba's LLVM variants crash on LLVM 15)"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libllvm19 >/dev/null
fi

PY="${PYTHON:-}"
if [ -z "$PY" ]; then
  for cand in python3.11 python3; do
    if command -v "$cand" >/dev/null && "$cand" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
      PY="$cand"; break
    fi
  done
fi
if [ -z "$PY" ]; then
  echo "setup: Python 3.11 is required (bpy 5.0.1 is built for 3.11 only)" >&2
  exit 2
fi

if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
# Exact versions from requirements.lock (pyproject.toml has ranges): a reproducible install, and numpy stays < 2
# (bpy 5.0.1 needs numpy 1.26). setuptools in the venv builds the wheel offline (tests/test_packaging.py).
LOCK=requirements.lock
.venv/bin/python -m pip install -q -c "$LOCK" --upgrade pip setuptools
# everything: the core and every extra (cycles, earth, cluster, spice, basilisk; see renderlab/extras.py) and the tests;
# `pip install renderlab` elsewhere gets the core only
.venv/bin/python -m pip install -q -c "$LOCK" -e ".[all,test]"
# the worked third-party plug-in (examples/ncc_baseline): installed like any user package, found by entry point
.venv/bin/python -m pip install -q -c "$LOCK" --no-deps -e examples/ncc_baseline
# the worked observable kind (examples/toy_kind: kind bright_spot with its methods and study), found by entry point
.venv/bin/python -m pip install -q -c "$LOCK" --no-deps -e examples/toy_kind
echo "setup: done. Run .venv/bin/renderlab --help"
