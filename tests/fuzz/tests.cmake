# libFuzzer target for the PLY reader (KDT_FUZZ=ON with clang; see the `fuzz` preset and
# scripts/run_fuzz.sh). The reader's sources are compiled into the fuzzer itself so they
# get coverage instrumentation.
if(KDT_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(STATUS "kdtrace: KDT_FUZZ needs clang; not building ply_fuzzer")
  else()
    add_executable(ply_fuzzer ${CMAKE_CURRENT_LIST_DIR}/ply_fuzzer.cpp
                   ${CMAKE_SOURCE_DIR}/renderer/io/ply_reader.cpp
                   ${CMAKE_SOURCE_DIR}/renderer/io/file_reader.cpp)
    target_link_libraries(ply_fuzzer PRIVATE kdt_geometry ZLIB::ZLIB kdt_options)
    target_compile_options(ply_fuzzer PRIVATE -fsanitize=fuzzer -Wall -Wextra -Werror)
    target_link_options(ply_fuzzer PRIVATE -fsanitize=fuzzer)
    set(KDT_FUZZ_SECONDS 60 CACHE STRING "Seconds the ply_fuzz test runs the fuzzer")
    # `ctest --preset fuzz` runs it on a fresh copy of the seed corpus.
    add_test(NAME ply_fuzz
             COMMAND ${CMAKE_COMMAND} -E env KDT_FUZZ_SECONDS=${KDT_FUZZ_SECONDS}
                     KDT_FUZZER=$<TARGET_FILE:ply_fuzzer>
                     ${CMAKE_SOURCE_DIR}/scripts/run_fuzz.sh --no-build)
    set_tests_properties(ply_fuzz PROPERTIES LABELS fuzz TIMEOUT 600)
    message(STATUS "kdtrace: building ply_fuzzer (libFuzzer)")
  endif()
endif()
