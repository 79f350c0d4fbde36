# Builds the simulation layers (state_hash) with another compiler (clang++) in its own tree and checks that it gives
# the same drill state hash as the committed value, which the GCC build also asserts.
# cmake -DSRC=<repo> -DBIN=<tree> -DCXX=<clang++> -DCC=<clang> -DSTEPS=<n> -DHASH=<hex> -P cross_compiler.cmake
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SRC} -B ${BIN} -DCMAKE_BUILD_TYPE=Release
                        -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_C_COMPILER=${CC}
                        -DCROWDMPM_BUILD_BENCHMARKS=OFF -DCROWDMPM_SKIP_BINDINGS=ON
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "configuring the ${CXX} build failed")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} --build ${BIN} --target state_hash -j2 RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "building state_hash with ${CXX} failed")
endif()
foreach(threads 1 2)
  execute_process(COMMAND ${BIN}/tests/state_hash ${SRC}/scenarios/drill.json ${STEPS} ${threads}
                  OUTPUT_VARIABLE out OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE rc)
  string(TOLOWER "${HASH}" expected)
  if(NOT rc EQUAL 0 OR NOT out STREQUAL expected)
    message(FATAL_ERROR "${CXX} build, ${threads} thread(s): drill hash '${out}' differs from the GCC build's ${expected}")
  endif()
  message("${CXX} build, ${threads} thread(s): drill hash ${out} (same as GCC)")
endforeach()
