# `cmake --install <build> --prefix <dir>`: the flight libraries, their
# headers and the CMake package, so that another project writes
#   find_package(proxops 0.1 REQUIRED)
#   target_link_libraries(app PRIVATE proxops::fsw_core)
# (tests/cmake/consumer is such a project; ctest builds it against an
# install of this tree).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(PROXOPS_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/proxops)
set(_proxops_targets fsw_core)
if(TARGET fsw_vision)
  list(APPEND _proxops_targets fsw_vision)
  set(PROXOPS_HAVE_VISION ON)
else()
  set(PROXOPS_HAVE_VISION OFF)
endif()

install(TARGETS ${_proxops_targets} EXPORT proxopsTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/fsw/include/fsw DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        FILES_MATCHING PATTERN "*.hpp")
if(PROXOPS_HAVE_VISION)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/fsw/vision/include/fsw_vision DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
          FILES_MATCHING PATTERN "*.hpp")
endif()
install(EXPORT proxopsTargets NAMESPACE proxops:: DESTINATION ${PROXOPS_INSTALL_CMAKEDIR})

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/proxopsConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/proxopsConfig.cmake
                              INSTALL_DESTINATION ${PROXOPS_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/proxopsConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/proxopsConfig.cmake ${PROJECT_BINARY_DIR}/proxopsConfigVersion.cmake
        DESTINATION ${PROXOPS_INSTALL_CMAKEDIR})
