# SPDX-License-Identifier: MIT
"""`pio pkg pack` without a network: PlatformIO checks library.json's "license" against SPDX's
licence list, which it downloads from GitHub on every run. Here that list holds the one licence
ctrlbus uses (MIT), so the check still fails on any other value; everything else (manifest
validation, the export include/exclude rules, the archive) is PlatformIO's own code.

    python scripts/pio_pack.py [pio pkg pack arguments...]   # e.g. -o dist/ .
"""

import sys

from platformio.__main__ import main
from platformio.package.manifest.schema import ManifestSchema

ManifestSchema.load_spdx_licenses = staticmethod(lambda: {"licenses": [{"licenseId": "MIT"}]})

if __name__ == "__main__":
    sys.exit(main(["pio", "pkg", "pack", *sys.argv[1:]]))
