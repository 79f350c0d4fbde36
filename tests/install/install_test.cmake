# cmake --install into a fresh prefix, then use the installed tree as an outside project would:
#  1. find_package(crowdmpm CONFIG) + crowdmpm::crowdmpm from a CMake project (consumer/);
#  2. pkg-config --cflags --libs crowdmpm with the C compiler;
#  3. the installed CLI on the installed drill scenario.
# Both programs must print the committed drill hash. Needs: BIN, SRC, PREFIX, CC, STEPS, HASH.
foreach(v BIN SRC PREFIX CC STEPS HASH)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "install_test.cmake: -D${v}= is missing")
  endif()
endforeach()

function(run what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (${rc}):\n${ARGN}\n${out}\n${err}")
  endif()
  set(RUN_OUT "${out}" PARENT_SCOPE)
endfunction()

# Runs a consumer program on the installed drill; it must print the committed hash.
function(expect_hash what exe)
  run("running the ${what} consumer" ${CMAKE_COMMAND} -E env LD_LIBRARY_PATH=${libdir} ${exe} ${drill} ${STEPS})
  string(STRIP "${RUN_OUT}" out)
  message(STATUS "${what} consumer: ${out}")
  if(NOT out MATCHES "hash ${HASH}$")
    message(FATAL_ERROR "the ${what} consumer printed '${out}', expected hash ${HASH}")
  endif()
endfunction()

file(REMOVE_RECURSE ${PREFIX})
run("cmake --install" ${CMAKE_COMMAND} --install ${BIN} --prefix ${PREFIX})
file(GLOB_RECURSE libs LIST_DIRECTORIES false RELATIVE ${PREFIX} ${PREFIX}/*libcrowdmpm.so*)
list(SORT libs)
message(STATUS "installed libraries: ${libs}")
foreach(f include/crowdmpm/crowdmpm.h bin/crowdmpm share/crowdmpm/scenarios/drill.json
          share/crowdmpm/scenarios/models/learned_juelich.json)
  if(NOT EXISTS ${PREFIX}/${f})
    message(FATAL_ERROR "not installed: ${f}")
  endif()
endforeach()
# The versioned SONAME: libcrowdmpm.so -> libcrowdmpm.so.1 -> libcrowdmpm.so.<version>.
file(GLOB sonames ${PREFIX}/lib*/libcrowdmpm.so.1 ${PREFIX}/lib*/*/libcrowdmpm.so.1)
file(GLOB devlinks ${PREFIX}/lib*/libcrowdmpm.so ${PREFIX}/lib*/*/libcrowdmpm.so)
if(NOT sonames OR NOT devlinks)
  message(FATAL_ERROR "libcrowdmpm.so and libcrowdmpm.so.1 links are missing: ${libs}")
endif()
get_filename_component(libdir ${sonames} DIRECTORY)
set(drill ${PREFIX}/share/crowdmpm/scenarios/drill.json)

# 1. CMake package.
set(cbuild ${PREFIX}/_consumer_build)
run("configuring the consumer" ${CMAKE_COMMAND} -S ${SRC}/consumer -B ${cbuild} -DCMAKE_PREFIX_PATH=${PREFIX}
    -DCMAKE_C_COMPILER=${CC} -DCMAKE_BUILD_RULE_MESSAGES=OFF)
run("building the consumer" ${CMAKE_COMMAND} --build ${cbuild})
expect_hash("find_package" ${cbuild}/consumer)

# 2. pkg-config.
find_program(PKG_CONFIG pkg-config REQUIRED)
run("pkg-config" ${CMAKE_COMMAND} -E env PKG_CONFIG_PATH=${libdir}/pkgconfig ${PKG_CONFIG} --cflags --libs crowdmpm)
string(STRIP "${RUN_OUT}" flags)
separate_arguments(flags UNIX_COMMAND "${flags}")
run("compiling with pkg-config flags" ${CC} ${SRC}/consumer/consumer.c -o ${cbuild}/consumer_pc ${flags})
expect_hash("pkg-config" ${cbuild}/consumer_pc)

# 3. The installed CLI reads the installed scenarios.
run("the installed CLI" ${PREFIX}/bin/crowdmpm validate ${drill})
message(STATUS "installed CLI: ${RUN_OUT}")
file(REMOVE_RECURSE ${PREFIX})
