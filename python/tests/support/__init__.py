# SPDX-License-Identifier: MIT
"""What the tests share and are not tests themselves: processes and frame peers (base_harness),
the broken bases of the checker tests (broken_bases), fakes of the Core's parts (core_fakes), the
shipped bases started as users start them (served_bases), QEMU command lines (qemu), packaging
helpers (packaging_support), the test-vector files (vectorfiles) and the ROS 2 bridge's helpers
(ros2_support), and the core session in virtual time (core_session), real-time checker runs
(checker_runs)."""
