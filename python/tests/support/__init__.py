# SPDX-License-Identifier: MIT
"""What the tests share and are not tests themselves: processes and frame peers (base_harness),
the broken bases of the checker tests (broken_bases), fakes of the Core's parts (core_fakes), the
shipped bases started as users start them (served_bases), QEMU command lines (qemu), packaging
helpers (packaging_support) and the test-vector files (vectorfiles)."""
