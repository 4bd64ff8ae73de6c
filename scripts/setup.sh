#!/usr/bin/env bash
# Install everything lightcal needs into ./.venv (idempotent; re-runs only when
# pyproject.toml changed). Usage: bash scripts/setup.sh [--dev] [--browser] [--reference]
set -euo pipefail
cd "$(dirname "$0")/.."

extras=""
browser=0
reference=0
for arg in "$@"; do
  case "$arg" in
    --dev) extras="dev" ;;
    --browser) browser=1 ;;
    --reference) reference=1 ;;
    *) echo "setup.sh: unknown option $arg (expected --dev, --browser or --reference)" >&2; exit 2 ;;
  esac
done

if [ "$browser" = 1 ]; then
  extras="${extras:+$extras,}browser"
  if [ ! -x /usr/bin/chromium ]; then
    echo "setup: installing Debian's chromium for the browser tests"
    if [ "$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
  fi
fi

# Mitsuba 3 (and, further down, Blender's bpy), the independent renderers the wall models,
# the honesty tests and the exports are checked against. Mitsuba's fast llvm_ad_rgb
# variant needs an LLVM newer than Debian 12's default 15 (which aborts it); without one
# the tests fall back to scalar_rgb, ~5x slower.
if [ "$reference" = 1 ]; then
  extras="${extras:+$extras,}reference"
  if command -v apt-get >/dev/null && ! dpkg -s libllvm19 >/dev/null 2>&1; then
    echo "setup: installing Debian's libllvm19 for Mitsuba's llvm variant"
    if [ "$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi
    { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libllvm19 >/dev/null; } \
      || echo "setup: libllvm19 not installed: the Mitsuba tests use scalar_rgb" >&2
  fi
fi

PY="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
  .venv/bin/python -m pip install -q --upgrade pip
fi

# The stamp holds pyproject.toml's hash and the extras installed with it: the app's
# set-up after the tests' (fewer extras) installs nothing, and neither drops the other's.
stamp=".venv/.lightcal-installed"
hash="$(sha256sum pyproject.toml | cut -c1-16)"
have_hash="" have_extras=""
if [ -f "$stamp" ]; then read -r have_hash have_extras < "$stamp" || true; fi
have_extras="${have_extras#.}" && have_extras="${have_extras#[}" && have_extras="${have_extras%]}"
[ "$have_hash" = "$hash" ] || have_extras=""
union="$have_extras"
for e in ${extras//,/ }; do
  case ",$union," in *",$e,"*) ;; *) union="${union:+$union,}$e" ;; esac
done
if [ "$have_hash" != "$hash" ] || [ "$union" != "$have_extras" ]; then
  spec="."
  [ -n "$union" ] && spec=".[$union]"
  echo "setup: pip install -e '$spec'"
  .venv/bin/python -m pip install -q -e "$spec"
  echo "$hash $union" > "$stamp"
fi

# Blender as a Python module (bpy 5.0), the renderer the Blender export is checked against
# (tests/test_export_blender_render.py). It needs Python 3.11 and pins NumPy < 2, which
# this venv cannot take (opencv-python-headless 5 needs NumPy >= 2), so it gets a venv
# of its own inside this one, .venv/bpy (a 380 MB download, once), where the tests find
# it (or name another interpreter with LIGHTCAL_BPY_PYTHON). BPY_PYTHON: a Python 3.11.
if [ "$reference" = 1 ] && ! .venv/bpy/bin/python -c "import bpy" >/dev/null 2>&1; then
  BPY_PY="${BPY_PYTHON:-python3.11}"
  if command -v "$BPY_PY" >/dev/null \
    && "$BPY_PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
    echo "setup: installing bpy 5.0 (Blender as a Python module) into .venv/bpy"
    "$BPY_PY" -m venv .venv/bpy
    .venv/bpy/bin/python -m pip install -q "bpy>=5.0,<5.1" \
      || echo "setup: bpy not installed: the Blender render tests are skipped" >&2
  else
    echo "setup: no Python 3.11 ($BPY_PY) for bpy: the Blender render tests are skipped" >&2
  fi
fi

# Byte-compile lightcal's own modules (an editable install leaves them as sources; a
# shell with PYTHONDONTWRITEBYTECODE would recompile ~90 modules, 0.15 s, at every start).
.venv/bin/python -m compileall -q lightcal app/lightcal_app

# Compile the numba kernels now, with a progress line (once per install: one to a few
# minutes on two cores), so that no command or test run pays it in silence.
.venv/bin/lightcal warmup
