# SPDX-License-Identifier: MIT
"""What Python 3.11 added and ctrlbus uses, for Python 3.10 (Ubuntu 22.04, ROS 2 Humble).

`typing.Self` needs no stand-in: modules that use it import it from typing_extensions under
TYPE_CHECKING only (annotations are never evaluated at run time), so nothing is installed for it.
"""

from __future__ import annotations

import enum
import sys

__all__ = ["StrEnum"]

if sys.version_info >= (3, 11):
    from enum import StrEnum
else:

    class StrEnum(str, enum.Enum):
        """enum.StrEnum of Python 3.11: members are strings, and str() / format() give the value."""

        def __str__(self) -> str:
            return str(self.value)

        @staticmethod
        def _generate_next_value_(name: str, start: int, count: int, last_values: list[str]) -> str:
            return name.lower()
