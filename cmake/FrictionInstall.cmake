# Installs the headers, the library, the CLI and a CMake package:
#   find_package(friction CONFIG REQUIRED) gives friction::friction (and friction::headers for the
#   model templates alone).  The include directory reaches both targets through friction::headers'
#   INSTALL_INTERFACE.  scripts/run-tests.sh builds examples/cmake-project against an install.
include(CMakePackageConfigHelpers)

set(FRICTION_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/friction)

install(DIRECTORY include/friction DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS friction_headers friction_friction EXPORT frictionTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS friction-identify RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(EXPORT frictionTargets NAMESPACE friction:: DESTINATION ${FRICTION_INSTALL_CMAKEDIR})

configure_package_config_file(cmake/frictionConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/frictionConfig.cmake
  INSTALL_DESTINATION ${FRICTION_INSTALL_CMAKEDIR})
# 0.x: a minor release may change the API, so only the same MAJOR.MINOR is compatible.
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/frictionConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/frictionConfig.cmake
              ${CMAKE_CURRENT_BINARY_DIR}/frictionConfigVersion.cmake
        DESTINATION ${FRICTION_INSTALL_CMAKEDIR})
