# The installable build (issue 15): `cmake --install build --prefix P` gives
#   P/bin/artms-*                      the programs (and artms-report)
#   P/share/artms/data, .../config     the shipped data and configuration
#   P/share/artms/python/artms_tools   the Python package artms-report uses
#   P/include/artms/...                public headers of the exported libraries
#   P/<libdir>/libartms_*.a            the onboard stack
#   P/<libdir>/cmake/artms/            artmsConfig.cmake, its version file and
#                                      artmsTargets.cmake (namespace artms::)
# Programs find data and config at run time (artms/io/paths.hpp): the
# environment, then <exe_dir>/../share/artms, then the configured prefix.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# The build tree is laid out like an install for that lookup:
# build/bin/artms-* find build/share/artms/{data,config}, symlinks to the
# source's data/ and config/.
file(MAKE_DIRECTORY ${CMAKE_BINARY_DIR}/share/artms)
foreach(dir data config)
  file(CREATE_LINK ${CMAKE_SOURCE_DIR}/${dir} ${CMAKE_BINARY_DIR}/share/artms/${dir} SYMBOLIC)
endforeach()

# Fixed relative layout (bin/ beside share/artms/): paths.cpp looks for
# <exe_dir>/../share/artms.
set(ARTMS_INSTALL_SHAREDIR share/artms)
set(ARTMS_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/artms)

install(TARGETS
    artms_swarm artms_truth artms_observer artms_camera_renderer artms_crosslink_emulator
    artms_recorder artms_imp_tool artms_render artms_propagate artms_sod_replay
  RUNTIME DESTINATION bin)
install(PROGRAMS ${CMAKE_SOURCE_DIR}/tools/artms_report/artms_report.py DESTINATION bin RENAME artms-report)

install(DIRECTORY ${CMAKE_SOURCE_DIR}/data/ DESTINATION ${ARTMS_INSTALL_SHAREDIR}/data)
install(DIRECTORY ${CMAKE_SOURCE_DIR}/config/ DESTINATION ${ARTMS_INSTALL_SHAREDIR}/config)
# artms-report looks for artms_tools in <exe_dir>/../share/artms/python.
if(EXISTS ${CMAKE_SOURCE_DIR}/tools/python/artms_tools)
  install(DIRECTORY ${CMAKE_SOURCE_DIR}/tools/python/artms_tools DESTINATION ${ARTMS_INSTALL_SHAREDIR}/python
    FILES_MATCHING PATTERN "*.py" PATTERN "__pycache__" EXCLUDE)
endif()

# The onboard stack (fsw::Observer and what it links), exported as artms::<name>.
set(ARTMS_EXPORTED_LIBRARIES artms_astro artms_dynamics artms_io artms_config artms_imp artms_sod artms_bod
  artms_bus artms_fsw)
foreach(lib IN LISTS ARTMS_EXPORTED_LIBRARIES)
  string(REGEX REPLACE "^artms_" "" name ${lib})
  set_target_properties(${lib} PROPERTIES EXPORT_NAME ${name})
  get_target_property(src ${lib} SOURCE_DIR)
  install(DIRECTORY ${src}/include/ DESTINATION include)
endforeach()
install(TARGETS ${ARTMS_EXPORTED_LIBRARIES} EXPORT artmsTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION bin)
install(EXPORT artmsTargets NAMESPACE artms:: FILE artmsTargets.cmake DESTINATION ${ARTMS_INSTALL_CMAKEDIR})

set(ARTMS_INSTALL_DATADIR ${ARTMS_INSTALL_SHAREDIR}/data)
set(ARTMS_INSTALL_CONFIGDIR ${ARTMS_INSTALL_SHAREDIR}/config)
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/artmsConfig.cmake.in
  ${CMAKE_BINARY_DIR}/cmake/artmsConfig.cmake
  INSTALL_DESTINATION ${ARTMS_INSTALL_CMAKEDIR}
  PATH_VARS ARTMS_INSTALL_DATADIR ARTMS_INSTALL_CONFIGDIR)
# 0.x: a new minor version may break the interface.
write_basic_package_version_file(${CMAKE_BINARY_DIR}/cmake/artmsConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/cmake/artmsConfig.cmake ${CMAKE_BINARY_DIR}/cmake/artmsConfigVersion.cmake
  DESTINATION ${ARTMS_INSTALL_CMAKEDIR})
