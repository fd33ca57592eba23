# SPDX-License-Identifier: MIT
# Install rules of the ctrlbus library (included by c/CMakeLists.txt when CTRLBUS_INSTALL is on):
#   lib/libctrlbus.a, include/ctrlbus/*.h,
#   lib/cmake/ctrlbus/ (find_package(ctrlbus CONFIG): target ctrlbus::ctrlbus, version file),
#   lib/pkgconfig/ctrlbus.pc (relocatable: paths relative to the .pc file).
include(CMakePackageConfigHelpers)

set(ctrlbus_cmake_dir "${CMAKE_INSTALL_LIBDIR}/cmake/ctrlbus")
set(ctrlbus_pkgconfig_dir "${CMAKE_INSTALL_LIBDIR}/pkgconfig")

install(TARGETS ctrlbus EXPORT ctrlbusTargets
        ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}"
        LIBRARY DESTINATION "${CMAKE_INSTALL_LIBDIR}"
        INCLUDES DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}")
install(DIRECTORY "${CMAKE_CURRENT_SOURCE_DIR}/include/ctrlbus"
        DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}" FILES_MATCHING PATTERN "*.h")
install(EXPORT ctrlbusTargets NAMESPACE ctrlbus:: DESTINATION "${ctrlbus_cmake_dir}")

configure_package_config_file("${CMAKE_CURRENT_LIST_DIR}/ctrlbusConfig.cmake.in"
                              "${CMAKE_CURRENT_BINARY_DIR}/ctrlbusConfig.cmake"
                              INSTALL_DESTINATION "${ctrlbus_cmake_dir}")
# Before 1.0 a minor release may change the API, so only the same minor version is compatible.
write_basic_package_version_file("${CMAKE_CURRENT_BINARY_DIR}/ctrlbusConfigVersion.cmake"
                                 COMPATIBILITY SameMinorVersion)
install(FILES "${CMAKE_CURRENT_BINARY_DIR}/ctrlbusConfig.cmake"
              "${CMAKE_CURRENT_BINARY_DIR}/ctrlbusConfigVersion.cmake"
        DESTINATION "${ctrlbus_cmake_dir}")

# The .pc file finds the prefix from its own place, so `cmake --install --prefix` anywhere works.
file(RELATIVE_PATH ctrlbus_pc_to_prefix "/prefix/${ctrlbus_pkgconfig_dir}" "/prefix")
string(REGEX REPLACE "/$" "" ctrlbus_pc_to_prefix "${ctrlbus_pc_to_prefix}")
configure_file("${CMAKE_CURRENT_LIST_DIR}/ctrlbus.pc.in" "${CMAKE_CURRENT_BINARY_DIR}/ctrlbus.pc" @ONLY)
install(FILES "${CMAKE_CURRENT_BINARY_DIR}/ctrlbus.pc" DESTINATION "${ctrlbus_pkgconfig_dir}")
