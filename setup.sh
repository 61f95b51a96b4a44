#!/usr/bin/env bash
# One-command set-up on a fresh Debian machine: LLVM 19 for Mitsuba's LLVM variants, a Python 3.11
# virtual environment in .venv, and renderlab installed into it (editable) with its test extras.
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
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[test]"
# the worked third-party plug-in (examples/ncc_baseline): installed like any user package, found by entry point
.venv/bin/python -m pip install -q --no-deps -e examples/ncc_baseline
echo "setup: done. Run .venv/bin/renderlab --help"
