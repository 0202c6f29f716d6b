# Installs the already-built wiretape into a temporary prefix, then configures,
# builds and runs tests/consumer against it with find_package(wiretape): first
# without GoogleTest (the library alone must not need it), then with its
# driver test (the testing component), which records its cassette and
# replays it. docs/port.md shows this CMakeLists.txt and driver test: they
# must be these files.
file(REMOVE_RECURSE "${WORK_DIR}")
set(prefix "${WORK_DIR}/prefix")
set(consumer "${WIRETAPE_SOURCE_DIR}/tests/consumer")

function(check_doc_block file)
  file(READ "${WIRETAPE_SOURCE_DIR}/docs/port.md" doc)
  file(READ "${consumer}/${file}" wanted)
  string(FIND "${doc}" "<!-- This block is tests/consumer/${file}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "docs/port.md shows no tests/consumer/${file}")
  endif()
  string(SUBSTRING "${doc}" ${at} -1 doc)
  string(REGEX MATCH "```[a-z]*\n([^`]*)```" _ "${doc}")
  if(NOT CMAKE_MATCH_1 STREQUAL wanted)
    message(FATAL_ERROR "docs/port.md's block differs from tests/consumer/${file}: "
                        "keep the two identical")
  endif()
endfunction()
check_doc_block(CMakeLists.txt)
check_doc_block(consumer_test.cpp)

function(run what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  if(rc)
    message(FATAL_ERROR "${what} failed (exit ${rc}):\n${out}")
  endif()
  set(output "${out}" PARENT_SCOPE)
endfunction()

run("installing wiretape into ${prefix}"
    ${CMAKE_COMMAND} --install "${WIRETAPE_BINARY_DIR}" --prefix "${prefix}" --component cpp)

# The library alone, GoogleTest out of reach.
run("configuring the consumer with find_package(wiretape) and no GoogleTest"
    ${CMAKE_COMMAND} -S "${consumer}" -B "${WORK_DIR}/build" -G "${GENERATOR}"
    "-DCMAKE_PREFIX_PATH=${prefix}" -DMY_DRIVER_TESTS=OFF -DCMAKE_DISABLE_FIND_PACKAGE_GTest=ON)
run("building the consumer" ${CMAKE_COMMAND} --build "${WORK_DIR}/build")
execute_process(COMMAND "${WORK_DIR}/build/consumer" WORKING_DIRECTORY "${WORK_DIR}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out)
message(STATUS "consumer printed: ${out}")
if(rc OR NOT out MATCHES "live:   PING\n.*replay: PING\n")
  message(FATAL_ERROR "the consumer did not run as expected (exit ${rc})")
endif()

# The testing component without GoogleTest: refused, naming it.
execute_process(COMMAND ${CMAKE_COMMAND} -S "${consumer}" -B "${WORK_DIR}/no-gtest" -G "${GENERATOR}"
                        "-DCMAKE_PREFIX_PATH=${prefix}" -DCMAKE_DISABLE_FIND_PACKAGE_GTest=ON
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
if(NOT rc OR NOT out MATCHES "GTest")
  message(FATAL_ERROR "find_package(wiretape COMPONENTS testing) without GoogleTest must fail "
                      "naming GTest (exit ${rc}):\n${out}")
endif()

# The driver test: recorded from a loopback device, then replayed.
run("configuring the consumer with find_package(wiretape COMPONENTS testing)"
    ${CMAKE_COMMAND} -S "${consumer}" -B "${WORK_DIR}/build" -DMY_DRIVER_TESTS=ON
    -DCMAKE_DISABLE_FIND_PACKAGE_GTest=OFF)
run("building the consumer's driver test" ${CMAKE_COMMAND} --build "${WORK_DIR}/build")
set(cassettes "WIRETAPE_CASSETTE_DIR=${WORK_DIR}/cassettes")
run("recording the driver test's cassette"
    ${CMAKE_COMMAND} -E env WIRETAPE_RECORD=1 WIRETAPE_DEVICE=type=loopback "${cassettes}"
    "${WORK_DIR}/build/consumer_test")
if(NOT EXISTS "${WORK_DIR}/cassettes/consumer_test/EchoTest.AnswersPing.wtape")
  message(FATAL_ERROR "the driver test recorded no cassette:\n${output}")
endif()
run("replaying the driver test's cassette"
    ${CMAKE_COMMAND} -E env --unset=WIRETAPE_RECORD --unset=WIRETAPE_DEVICE "${cassettes}"
    "${WORK_DIR}/build/consumer_test")
