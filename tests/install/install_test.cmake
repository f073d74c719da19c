# Installs the build into a fresh prefix and uses it the three documented ways
# (README "Use it from your code"): the CMake package (consumer/CMakeLists.txt),
# pkg-config (Vulkan-free formats_check.cpp, and consumer/main.cpp against the
# runtime) and the Python module (consumer/render.py). Each consumer of the
# runtime renders a PNG; formats/ needs no Vulkan, by CMake component and pkg-config.
#   cmake -DBUILD=<build dir> -DSOURCE=<this folder> -DWORK=<scratch> -DCXX=<c++> [-DPYTHON=<python3>] -P install_test.cmake
# Without PYTHON (a build with -DPENUMBRA_BUILD_PYTHON=OFF) the Python step is skipped.
foreach(variable BUILD SOURCE WORK CXX)
  if(NOT ${variable})
    message(FATAL_ERROR "install_test.cmake: -D${variable}=... is required")
  endif()
endforeach()

function(run)
  cmake_parse_arguments(RUN "" "DIRECTORY" "" ${ARGN})
  if(NOT RUN_DIRECTORY)
    set(RUN_DIRECTORY ${WORK})
  endif()
  execute_process(COMMAND ${RUN_UNPARSED_ARGUMENTS} WORKING_DIRECTORY ${RUN_DIRECTORY}
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  message(STATUS "$ ${RUN_UNPARSED_ARGUMENTS}\n${out}${err}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${RUN_UNPARSED_ARGUMENTS}")
  endif()
  if(err MATCHES "penumbra: validation")   # PENUMBRA_VALIDATION=1: any message fails
    message(FATAL_ERROR "Vulkan validation messages: ${RUN_UNPARSED_ARGUMENTS}")
  endif()
  string(STRIP "${out}" out)
  set(output "${out}" PARENT_SCOPE)
endfunction()

function(expect_image path)
  if(NOT EXISTS ${path})
    message(FATAL_ERROR "${path} was not written")
  endif()
  file(SIZE ${path} bytes)
  file(READ ${path} magic LIMIT 4 HEX)
  if(bytes LESS 1000 OR NOT magic STREQUAL "89504e47")
    message(FATAL_ERROR "${path} is not a PNG with content (${bytes} bytes, starts ${magic})")
  endif()
endfunction()

set(prefix ${WORK}/prefix)
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK}/python)
run(${CMAKE_COMMAND} --install ${BUILD} --prefix ${prefix})

# CMake: find_package(Penumbra CONFIG REQUIRED), Penumbra::penumbra.
run(${CMAKE_COMMAND} -S ${SOURCE}/consumer -B ${WORK}/cmake -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX}
    -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF)
run(${CMAKE_COMMAND} --build ${WORK}/cmake)
run(${WORK}/cmake/render_city ${WORK}/cmake.png)
expect_image(${WORK}/cmake.png)

# CMake, formats alone: COMPONENTS formats, Penumbra::formats.
run(${CMAKE_COMMAND} -S ${SOURCE}/formats -B ${WORK}/cmake-formats -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX}
    -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF)
run(${CMAKE_COMMAND} --build ${WORK}/cmake-formats)
run(${WORK}/cmake-formats/formats_check ${WORK}/cmake-triangle.ply)

# pkg-config, relocated prefix: penumbra-formats needs no Vulkan; penumbra is the runtime.
set(ENV{PKG_CONFIG_PATH} ${prefix}/lib/pkgconfig)
run(pkg-config --cflags --libs penumbra-formats)
separate_arguments(flags UNIX_COMMAND "${output}")
if(flags MATCHES "vulkan|OpenImageIO")
  message(FATAL_ERROR "penumbra-formats.pc pulls in the runtime's dependencies: ${output}")
endif()
run(${CXX} ${SOURCE}/formats/formats_check.cpp ${flags} -o ${WORK}/formats_check)
run(${WORK}/formats_check ${WORK}/triangle.ply)
run(pkg-config --cflags --libs penumbra)
separate_arguments(flags UNIX_COMMAND "${output}")
run(${CXX} ${SOURCE}/consumer/main.cpp ${flags} -o ${WORK}/render_city_pkgconfig)
run(${WORK}/render_city_pkgconfig ${WORK}/pkgconfig.png)
expect_image(${WORK}/pkgconfig.png)

# Python: the installed module, from a folder of its own.
if(PYTHON)
  set(ENV{PYTHONPATH} ${prefix}/lib/python3/dist-packages)
  run(${PYTHON} ${SOURCE}/consumer/render.py DIRECTORY ${WORK}/python)
  expect_image(${WORK}/python/city.png)
endif()

# The installed CLI needs nothing from the build tree (SPIR-V is embedded).
run(${prefix}/bin/penumbra generate city --triangles 20000 -o ${WORK}/city.ply)
run(${prefix}/bin/penumbra render ${WORK}/city.ply -o ${WORK}/cli.png --size 160x120 --shadows srt)
expect_image(${WORK}/cli.png)
