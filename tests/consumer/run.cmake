# Installs the already-built wiretape into a temporary prefix, then configures,
# builds and runs tests/consumer against it with find_package(wiretape).
file(REMOVE_RECURSE "${WORK_DIR}")
set(prefix "${WORK_DIR}/prefix")
execute_process(COMMAND ${CMAKE_COMMAND} --install "${WIRETAPE_BINARY_DIR}" --prefix "${prefix}" --component cpp
                RESULT_VARIABLE rc)
if(rc)
  message(FATAL_ERROR "installing wiretape into ${prefix} failed")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -S "${WIRETAPE_SOURCE_DIR}/tests/consumer" -B "${WORK_DIR}/build"
                        -G "${GENERATOR}" "-DCMAKE_PREFIX_PATH=${prefix}"
                RESULT_VARIABLE rc)
if(rc)
  message(FATAL_ERROR "configuring the consumer with find_package(wiretape) failed")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} --build "${WORK_DIR}/build" RESULT_VARIABLE rc)
if(rc)
  message(FATAL_ERROR "building the consumer failed")
endif()
execute_process(COMMAND "${WORK_DIR}/build/consumer" WORKING_DIRECTORY "${WORK_DIR}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out)
message(STATUS "consumer printed: ${out}")
if(rc OR NOT out MATCHES "live:   PING\n.*replay: PING\n")
  message(FATAL_ERROR "the consumer did not run as expected (exit ${rc})")
endif()
