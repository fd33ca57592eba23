import sys

from ctrlbus.cli import main

sys.exit(main())
