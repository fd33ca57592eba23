# SPDX-License-Identifier: MIT
"""Builds the Arduino library zip: ctrlbus-<version>-arduino.zip, one folder `ctrlbus/` in the
layout the Arduino IDE and arduino-cli install ("Add .ZIP Library", `arduino-cli lib install
--zip-path`):

    ctrlbus/library.properties         from packaging/arduino/library.properties.in
    ctrlbus/LICENSE, CHANGELOG.md
    ctrlbus/src/ctrlbus.h              the header a sketch includes (packaging/arduino/)
    ctrlbus/src/ctrlbus/*.h            c/include/ctrlbus/
    ctrlbus/src/...                    c/src/ (every file, subfolders kept)
    ctrlbus/examples/*/*.ino           packaging/arduino/examples/

    python scripts/arduino_zip.py OUTPUT_DIR     # prints the zip's path
"""

import sys
import zipfile
from pathlib import Path

from ctrlbus_version import REPO, ctrlbus_version

ARDUINO = REPO / "packaging" / "arduino"


def members() -> list[tuple[str, Path | str]]:
    """(path in the zip below ctrlbus/, source file or text), in a stable order."""
    version = ctrlbus_version()
    properties = (ARDUINO / "library.properties.in").read_text().replace("@VERSION@", version)
    found: list[tuple[str, Path | str]] = [
        ("library.properties", properties),
        ("LICENSE", REPO / "LICENSE"),
        ("CHANGELOG.md", REPO / "CHANGELOG.md"),
        ("src/ctrlbus.h", ARDUINO / "ctrlbus.h"),
    ]
    for header in sorted((REPO / "c" / "include" / "ctrlbus").glob("*.h")):
        found.append((f"src/ctrlbus/{header.name}", header))
    source_dir = REPO / "c" / "src"
    for source in sorted(p for p in source_dir.rglob("*") if p.is_file()):
        found.append((f"src/{source.relative_to(source_dir).as_posix()}", source))
    examples = ARDUINO / "examples"
    for example in sorted(p for p in examples.rglob("*") if p.is_file()):
        found.append((f"examples/{example.relative_to(examples).as_posix()}", example))
    return found


def build(output_dir: Path) -> Path:
    output_dir.mkdir(parents=True, exist_ok=True)
    path = output_dir / f"ctrlbus-{ctrlbus_version()}-arduino.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, source in members():
            data = source if isinstance(source, str) else source.read_bytes()
            archive.writestr(f"ctrlbus/{name}", data)
    return path


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: arduino_zip.py OUTPUT_DIR")
    print(build(Path(sys.argv[1])))
