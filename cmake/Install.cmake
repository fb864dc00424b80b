# Install rules: headers, the two libraries, the program, a CMake package and pkg-config files.
#   cmake --install build --prefix P
# P/include/octovk/*                       headers (device_types.h is shared with the shaders)
# P/lib*/liboctovk.a, liboctovk_octomap.a  the core (SPIR-V embedded) and OctoMap's formats
# P/lib*/liboctovk_store.a                 the map store (SQLite and PostgreSQL; always static)
# P/bin/octovk                             the program
# P/lib*/cmake/octovk/                     find_package(octovk): octovk::octovk, octovk::octomap,
#                                          octovk::store
# P/lib*/pkgconfig/octovk.pc, octovk-octomap.pc, octovk-store.pc
# Everything is relocatable: the CMake files and the .pc files locate the prefix from their own
# place, so --prefix may differ from CMAKE_INSTALL_PREFIX.
include(CMakePackageConfigHelpers)

set(OCTOVK_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/octovk)

# Shared libraries (-DBUILD_SHARED_LIBS=ON; static is the default): the installed program and
# liboctovk_octomap find theirs relative to themselves.
if(BUILD_SHARED_LIBS AND NOT IS_ABSOLUTE ${CMAKE_INSTALL_BINDIR} AND NOT IS_ABSOLUTE ${CMAKE_INSTALL_LIBDIR})
  file(RELATIVE_PATH octovk_bin_to_lib /${CMAKE_INSTALL_BINDIR} /${CMAKE_INSTALL_LIBDIR})
  set_target_properties(octovk_cli PROPERTIES INSTALL_RPATH "$ORIGIN/${octovk_bin_to_lib}")
  set_target_properties(octovk_octomap PROPERTIES INSTALL_RPATH "$ORIGIN")
endif()

install(TARGETS octovk EXPORT octovkTargets)
install(TARGETS octovk_octomap EXPORT octovkOctomapTargets)
install(TARGETS octovk_store EXPORT octovkStoreTargets)
install(TARGETS octovk_cli)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/octovk DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
  FILES_MATCHING PATTERN "*.h" PATTERN "*.hpp")

# Three export sets, so that the core package never needs OctoMap, nor the OctoMap component
# SQLite or libpq: octovkConfig.cmake loads the second only when OctoMap is wanted (or found),
# the third only when the store is asked for.
install(EXPORT octovkTargets NAMESPACE octovk:: DESTINATION ${OCTOVK_CMAKE_DIR})
install(EXPORT octovkOctomapTargets NAMESPACE octovk:: DESTINATION ${OCTOVK_CMAKE_DIR})
install(EXPORT octovkStoreTargets NAMESPACE octovk:: DESTINATION ${OCTOVK_CMAKE_DIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/octovkConfig.cmake.in
  ${PROJECT_BINARY_DIR}/octovkConfig.cmake INSTALL_DESTINATION ${OCTOVK_CMAKE_DIR})
# 0.x: a new minor version may change the API.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/octovkConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/octovkConfig.cmake ${PROJECT_BINARY_DIR}/octovkConfigVersion.cmake
  DESTINATION ${OCTOVK_CMAKE_DIR})

# pkg-config: prefix relative to the .pc file's directory (${pcfiledir}) unless the install
# directories are absolute.
set(OCTOVK_PKGCONFIG_DIR ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
if(IS_ABSOLUTE ${OCTOVK_PKGCONFIG_DIR})
  set(OCTOVK_PC_PREFIX ${CMAKE_INSTALL_PREFIX})
else()
  file(RELATIVE_PATH octovk_pc_up /${OCTOVK_PKGCONFIG_DIR} /)
  string(REGEX REPLACE "/$" "" octovk_pc_up "${octovk_pc_up}")
  set(OCTOVK_PC_PREFIX "\${pcfiledir}/${octovk_pc_up}")
endif()
foreach(dir LIBDIR INCLUDEDIR)
  if(IS_ABSOLUTE ${CMAKE_INSTALL_${dir}})
    set(OCTOVK_PC_${dir} ${CMAKE_INSTALL_${dir}})
  else()
    set(OCTOVK_PC_${dir} "\${prefix}/${CMAKE_INSTALL_${dir}}")
  endif()
endforeach()
foreach(pc octovk octovk-octomap octovk-store)
  configure_file(${PROJECT_SOURCE_DIR}/cmake/${pc}.pc.in ${PROJECT_BINARY_DIR}/${pc}.pc @ONLY)
  install(FILES ${PROJECT_BINARY_DIR}/${pc}.pc DESTINATION ${OCTOVK_PKGCONFIG_DIR})
endforeach()
