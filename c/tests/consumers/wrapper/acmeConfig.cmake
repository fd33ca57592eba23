# SPDX-License-Identifier: MIT
# find_package(acme CONFIG): acme::acme_base, which needs ctrlbus::ctrlbus (installed beside it).
include(CMakeFindDependencyMacro)
find_dependency(ctrlbus CONFIG)
include("${CMAKE_CURRENT_LIST_DIR}/acme.cmake")
