# Third-party dependencies, all from Debian packages (libdraco-dev libmeshoptimizer-dev libglm-dev libzstd-dev libxxhash-dev
# libstb-dev).
include(GNUInstallDirs)
find_package(Threads REQUIRED)
find_package(glm REQUIRED)
find_package(draco REQUIRED)
find_package(meshoptimizer REQUIRED)

# Debian's zstd config exports only zstd::libzstd_shared / zstd::libzstd_static; older
# distributions ship no config at all, so fall back to pkg-config.
find_package(zstd CONFIG QUIET)
add_library(facetree_zstd INTERFACE)
if(TARGET zstd::libzstd_shared)
  target_link_libraries(facetree_zstd INTERFACE zstd::libzstd_shared)
elseif(TARGET zstd::libzstd_static)
  target_link_libraries(facetree_zstd INTERFACE zstd::libzstd_static)
else()
  find_package(PkgConfig REQUIRED)
  pkg_check_modules(ZSTD REQUIRED IMPORTED_TARGET libzstd)
  target_link_libraries(facetree_zstd INTERFACE PkgConfig::ZSTD)
endif()

# stb_image_write (header only) for PNG pictures.
find_path(STB_INCLUDE_DIR stb_image_write.h PATH_SUFFIXES stb REQUIRED)
add_library(facetree_stb INTERFACE)
target_include_directories(facetree_stb SYSTEM INTERFACE ${STB_INCLUDE_DIR})

# XXH64, the cluster file's checksum (libxxhash-dev: pkg-config only).
find_package(PkgConfig REQUIRED)
pkg_check_modules(XXHASH REQUIRED IMPORTED_TARGET libxxhash)
add_library(facetree_xxhash INTERFACE)
target_link_libraries(facetree_xxhash INTERFACE PkgConfig::XXHASH)
