# SPDX-License-Identifier: MIT
import sys

from ctrlbus.cli import main

sys.exit(main())
