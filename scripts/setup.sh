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

# Mitsuba 3, the independent renderer the wall models and the honesty tests are checked
# against. Its fast llvm_ad_rgb variant needs an LLVM newer than Debian 12's default 15
# (which aborts it); without one the tests fall back to scalar_rgb, ~5x slower.
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

# Byte-compile lightcal's own modules (an editable install leaves them as sources; a
# shell with PYTHONDONTWRITEBYTECODE would recompile ~90 modules, 0.15 s, at every start).
.venv/bin/python -m compileall -q lightcal app/lightcal_app

# Compile the numba kernels now, with a progress line (once per install: one to a few
# minutes on two cores), so that no command or test run pays it in silence.
.venv/bin/lightcal warmup
