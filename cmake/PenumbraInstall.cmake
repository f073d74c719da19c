# Install and package (issue #21): `cmake --install build --prefix P` installs
#   P/lib/libpenumbra_{formats,preprocess,runtime}.a    static libraries
#   P/include/penumbra/*.h                             public headers
#   P/bin/penumbra                                     the CLI (SPIR-V is embedded: nothing else at run time)
#   P/lib/cmake/Penumbra/                              find_package(Penumbra CONFIG): Penumbra::penumbra
#                                                      (the runtime), Penumbra::formats, Penumbra::preprocess
#   P/lib/pkgconfig/penumbra{,-preprocess,-formats}.pc pkg-config
#   P/lib/python3/dist-packages/penumbra*.so           the Python module (python/CMakeLists.txt)
# The internal interface libraries (penumbra_warnings, penumbra_shaders) stay
# out of the exported link interfaces ($<BUILD_INTERFACE:...> where they are linked).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(PENUMBRA_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/Penumbra)

# The names other projects see, the same inside this build (Penumbra::penumbra is the runtime).
set_target_properties(penumbra_formats PROPERTIES EXPORT_NAME formats)
set_target_properties(penumbra_preprocess PROPERTIES EXPORT_NAME preprocess)
add_library(Penumbra::formats ALIAS penumbra_formats)
add_library(Penumbra::preprocess ALIAS penumbra_preprocess)
if(PENUMBRA_BUILD_RUNTIME)
  set_target_properties(penumbra_runtime PROPERTIES EXPORT_NAME penumbra)
  add_library(Penumbra::penumbra ALIAS penumbra_runtime)
endif()
# The public headers use C++20 (<span>, designated initializers in examples).
target_compile_features(penumbra_formats PUBLIC cxx_std_20)

# Two export sets, so that formats/preprocess users need no Vulkan: the runtime's
# targets file is read only when the penumbra component is asked for.
install(TARGETS penumbra-preprocess RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(TARGETS penumbra_formats penumbra_preprocess EXPORT PenumbraTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT PenumbraTargets NAMESPACE Penumbra:: DESTINATION ${PENUMBRA_INSTALL_CMAKEDIR})
foreach(folder formats preprocess runtime)
  if(folder STREQUAL "runtime" AND NOT PENUMBRA_BUILD_RUNTIME)
    continue()
  endif()
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${folder}/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.h")
endforeach()
if(PENUMBRA_BUILD_RUNTIME)
  install(TARGETS penumbra_runtime EXPORT PenumbraRuntimeTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  install(EXPORT PenumbraRuntimeTargets NAMESPACE Penumbra:: DESTINATION ${PENUMBRA_INSTALL_CMAKEDIR})
  install(TARGETS penumbra RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()

configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/PenumbraConfig.cmake.in ${CMAKE_CURRENT_BINARY_DIR}/PenumbraConfig.cmake
                              INSTALL_DESTINATION ${PENUMBRA_INSTALL_CMAKEDIR})
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/PenumbraConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/PenumbraConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/PenumbraConfigVersion.cmake
        DESTINATION ${PENUMBRA_INSTALL_CMAKEDIR})

# pkg-config: one file per library; static archives, so each lists its
# dependencies in Libs/Requires (not .private). penumbra.pc is the runtime.
# Relocatable: prefix is found from the .pc file's own folder.
set(pc_dir ${CMAKE_CURRENT_BINARY_DIR}/pkgconfig)
file(RELATIVE_PATH PC_PREFIX /root/${CMAKE_INSTALL_LIBDIR}/pkgconfig /root)
string(REGEX REPLACE "/$" "" PC_PREFIX "${PC_PREFIX}")   # ../.. (lib) or ../../.. (lib/<multiarch>)
function(penumbra_pkg_config name library description requires libs)
  set(PC_NAME ${name})
  set(PC_LIBRARY ${library})
  set(PC_DESCRIPTION ${description})
  set(PC_REQUIRES ${requires})
  set(PC_LIBS ${libs})
  configure_file(${PROJECT_SOURCE_DIR}/cmake/penumbra.pc.in ${pc_dir}/${name}.pc @ONLY)
  install(FILES ${pc_dir}/${name}.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
endfunction()
penumbra_pkg_config(penumbra-formats penumbra_formats "Penumbra model importers/exporters and the .penumbra format (no Vulkan)"
                    "glm libxxhash draco" "-pthread")
penumbra_pkg_config(penumbra-preprocess penumbra_preprocess "Penumbra preprocessor and procedural scenes (no Vulkan)"
                    "penumbra-formats" "-lmeshoptimizer -pthread")
if(PENUMBRA_BUILD_RUNTIME)
  set(runtime_requires "penumbra-preprocess vulkan")
  if(PENUMBRA_WITH_OPENIMAGEIO)
    string(APPEND runtime_requires " OpenImageIO")
  endif()
  penumbra_pkg_config(penumbra penumbra_runtime "Penumbra headless Vulkan shadow renderer" "${runtime_requires}" "-pthread")
endif()
