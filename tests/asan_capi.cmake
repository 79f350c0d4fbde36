# Builds the C ABI and its C99 test with AddressSanitizer + UBSan in a separate tree and runs
# the test there: every misuse case must return its status without a memory error.
# cmake -DSRC=<repo> -DBIN=<tree> -P asan_capi.cmake
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SRC} -B ${BIN} -DCMAKE_BUILD_TYPE=Debug -DCROWDMPM_SANITIZE=ON
                        -DCROWDMPM_BUILD_BENCHMARKS=OFF
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "configuring the sanitizer build failed")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} --build ${BIN} --target test_capi -j2 RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "building test_capi with sanitizers failed")
endif()
set(ENV{ASAN_OPTIONS} "detect_leaks=1:abort_on_error=0:halt_on_error=1")
set(ENV{UBSAN_OPTIONS} "halt_on_error=1:print_stacktrace=1")
execute_process(COMMAND ${BIN}/tests/test_capi ${SRC} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "test_capi under AddressSanitizer/UBSan failed (exit ${rc})")
endif()
