# `cmake --install` puts the static library, the one public header of each module and a
# package config in the prefix, so another project can `find_package(facetree)`.
include(CMakePackageConfigHelpers)

# A sanitized library needs the sanitizer runtime in whatever links it, installed consumers too.
if(FACETREE_SANITIZE)
  target_link_options(facetree INTERFACE -fsanitize=address,undefined)
endif()

install(TARGETS facetree facetree_zstd facetree_xxhash EXPORT facetreeTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
if(TARGET facetree_cli)
  install(TARGETS facetree_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
# The public include tree as it is: <facetree.h> and <facetree/{error,stream,merge,grid,io}.h>.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

install(EXPORT facetreeTargets NAMESPACE facetree:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/facetree)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/facetreeConfig.cmake.in
  ${PROJECT_BINARY_DIR}/facetreeConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/facetree)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/facetreeConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/facetreeConfig.cmake ${PROJECT_BINARY_DIR}/facetreeConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/facetree)
