import sys

try:
    from lightcal.cli.main import entry
except KeyboardInterrupt:  # Ctrl-C while Python starts: no traceback either
    sys.exit(130)

sys.exit(entry())
