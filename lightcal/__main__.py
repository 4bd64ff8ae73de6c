import sys

from lightcal.cli.main import main

sys.exit(main())
