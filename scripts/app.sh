#!/usr/bin/env bash
# Install lightcal and open the calibration app on the bundled sample data
# (or on the project given as argument). Prints the URL to open in a browser.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/lightcal app "$@"
