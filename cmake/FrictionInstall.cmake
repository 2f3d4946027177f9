# Installs the headers, the library and a CMake package: find_package(friction CONFIG) gives
# friction::friction (and friction::headers for the model templates alone).
include(CMakePackageConfigHelpers)

install(DIRECTORY include/friction DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS friction_headers friction_friction EXPORT frictionTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS friction-identify RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(EXPORT frictionTargets NAMESPACE friction:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/friction)

configure_package_config_file(cmake/frictionConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/frictionConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/friction)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/frictionConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/frictionConfig.cmake
              ${CMAKE_CURRENT_BINARY_DIR}/frictionConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/friction)
