# Builds the C ABI and tests/threads/test_threads.cpp with ThreadSanitizer in a separate tree and
# runs it there: the thread contract's every allowed use, destroy during a step and concurrent
# destroys must run without a data race report.
# cmake -DSRC=<repo> -DBIN=<tree> -P tsan_threads.cmake
# -O1 -g1: line tables for the sanitizer's stack traces; builds in about 60% of RelWithDebInfo's time.
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SRC} -B ${BIN} -DCMAKE_BUILD_TYPE=None "-DCMAKE_CXX_FLAGS=-O1 -g1" "-DCMAKE_C_FLAGS=-O1 -g1" -DCROWDMPM_TSAN=ON
                        -DCROWDMPM_BUILD_BENCHMARKS=OFF
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "configuring the ThreadSanitizer build failed")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} --build ${BIN} --target test_threads -j2 RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "building test_threads with ThreadSanitizer failed")
endif()
set(ENV{TSAN_OPTIONS} "halt_on_error=1:second_deadlock_stack=1")
set(ENV{CROWDMPM_THREADS_ROUNDS} "100")
execute_process(COMMAND ${BIN}/tests/test_threads ${SRC} WORKING_DIRECTORY ${BIN} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "test_threads under ThreadSanitizer failed (exit ${rc})")
endif()
message(STATUS "test_threads ran clean under ThreadSanitizer")
