# `cmake --install` puts the static library, the one public header of each module and a
# package config in the prefix, so another project can `find_package(facetree)`.
include(CMakePackageConfigHelpers)

# A sanitized library needs the sanitizer runtime in whatever links it, installed consumers too.
if(FACETREE_SANITIZE)
  target_link_options(facetree INTERFACE -fsanitize=address,undefined)
endif()

install(TARGETS facetree facetree_zstd facetree_xxhash EXPORT facetreeTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/facetree)
if(TARGET facetree_cli)
  install(TARGETS facetree_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
foreach(module stream merge grid io)
  install(FILES ${PROJECT_SOURCE_DIR}/${module}/${module}.h
    DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/facetree/${module})
endforeach()
install(FILES ${PROJECT_SOURCE_DIR}/io/cluster_file.h ${PROJECT_SOURCE_DIR}/io/branching.h
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/facetree/io)
install(FILES ${PROJECT_SOURCE_DIR}/include/facetree/error.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/facetree/facetree)
install(FILES ${PROJECT_SOURCE_DIR}/cmake/facetree.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/facetree)

install(EXPORT facetreeTargets NAMESPACE facetree:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/facetree)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/facetreeConfig.cmake.in
  ${PROJECT_BINARY_DIR}/facetreeConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/facetree)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/facetreeConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/facetreeConfig.cmake ${PROJECT_BINARY_DIR}/facetreeConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/facetree)
