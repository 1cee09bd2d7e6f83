# libFuzzer targets for the readers of untrusted files (KDT_FUZZ=ON with clang; see the
# `fuzz` preset and scripts/run_fuzz.sh): PLY and OBJ meshes, kd-tree cache files, images,
# JSON scenes. The readers' sources are compiled into each fuzzer itself so they get coverage
# instrumentation. Each fuzzer is a ctest test labelled `fuzz` that runs it on a fresh copy
# of its seed corpus (tests/fuzz/corpus/<target>) for its share of the CI budget
# (scripts/run_fuzz.sh), or for KDT_FUZZ_SECONDS each when that is set. fuzz_seeds
# regenerates the seed corpora.
if(KDT_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(STATUS "kdtrace: KDT_FUZZ needs clang; not building the fuzzers")
  else()
    set(KDT_FUZZ_SECONDS "" CACHE STRING
        "Seconds each fuzz test runs its fuzzer (empty: the budgets in scripts/run_fuzz.sh)")
    set(_fuzz_dir ${CMAKE_CURRENT_LIST_DIR})
    set(_src ${CMAKE_SOURCE_DIR}/renderer)

    function(kdt_add_fuzzer name)
      add_executable(${name}_fuzzer ${_fuzz_dir}/${name}_fuzzer.cpp ${ARGN})
      target_include_directories(${name}_fuzzer PRIVATE ${CMAKE_SOURCE_DIR})
      target_compile_options(${name}_fuzzer PRIVATE -fsanitize=fuzzer -Wall -Wextra
                             -Wno-missing-field-initializers -Werror)
      target_link_options(${name}_fuzzer PRIVATE -fsanitize=fuzzer)
      add_test(NAME ${name}_fuzz
               COMMAND ${CMAKE_COMMAND} -E env KDT_FUZZ_SECONDS=${KDT_FUZZ_SECONDS}
                       KDT_FUZZER=$<TARGET_FILE:${name}_fuzzer>
                       ${CMAKE_SOURCE_DIR}/scripts/run_fuzz.sh --no-build ${name})
      set_tests_properties(${name}_fuzz PROPERTIES LABELS fuzz TIMEOUT 900)
    endfunction()

    # The PLY reader is split over renderer/io/ply_*.cpp; the writer is not part of it.
    file(GLOB _ply_src CONFIGURE_DEPENDS ${_src}/io/ply_*.cpp)
    list(REMOVE_ITEM _ply_src ${_src}/io/ply_writer.cpp)
    kdt_add_fuzzer(ply ${_ply_src} ${_src}/io/file_reader.cpp)
    target_link_libraries(ply_fuzzer PRIVATE kdt_geometry ZLIB::ZLIB kdt_options)

    kdt_add_fuzzer(obj ${_src}/io/obj_reader.cpp ${_src}/io/file_reader.cpp)
    target_link_libraries(obj_fuzzer PRIVATE kdt_geometry ZLIB::ZLIB kdt_options)

    # The whole accel module (loader, tree checks, single-ray and packet traversal); the
    # packet traversal only exists with AVX2, so it is compiled in when this machine has it.
    file(GLOB _accel_src CONFIGURE_DEPENDS ${_src}/accel/*.cpp)
    kdt_add_fuzzer(cache ${_accel_src})
    target_link_libraries(cache_fuzzer PRIVATE kdt_geometry OpenMP::OpenMP_CXX kdt_options)
    include(CheckCXXSourceRuns)
    check_cxx_source_runs("int main() { return __builtin_cpu_supports(\"avx2\") &&
                           __builtin_cpu_supports(\"fma\") ? 0 : 1; }" KDT_FUZZ_HOST_AVX2)
    if(KDT_FUZZ_HOST_AVX2)
      target_compile_options(cache_fuzzer PRIVATE -mavx2 -mfma)
    endif()

    # OpenEXR is Debian's shared library, not instrumented: ASan sees its heap accesses
    # only through the allocator and intercepted calls (memcpy, ...), and coverage stops at
    # its boundary (our header checks and exception handling are covered).
    kdt_add_fuzzer(image ${_src}/io/image_io.cpp ${_src}/io/exr_io.cpp)
    target_link_libraries(image_fuzzer PRIVATE kdt_core ZLIB::ZLIB OpenEXR::OpenEXR kdt_options)

    # The scene reader (nlohmann::json is header-only, so it is instrumented along with it).
    kdt_add_fuzzer(scene ${_src}/scene/scene.cpp ${_src}/scene/default_scene.cpp
                   ${_src}/scene/json_parse.cpp)
    target_link_libraries(scene_fuzzer PRIVATE kdt_io kdt_options)

    # Writes the seed corpora with the project's own writers (see the file for how to run it).
    add_executable(fuzz_seeds ${_fuzz_dir}/fuzz_seeds.cpp ${CMAKE_SOURCE_DIR}/tests/test_util.cpp)
    target_link_libraries(fuzz_seeds PRIVATE kdt_renderer kdt_warnings kdt_options)
    target_compile_definitions(fuzz_seeds PRIVATE KDT_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
    # Writes the image fuzzer's OpenEXR seeds (see the file).
    add_executable(exr_seeds ${_fuzz_dir}/exr_seeds.cpp ${CMAKE_SOURCE_DIR}/tests/test_util.cpp)
    target_link_libraries(exr_seeds PRIVATE kdt_io kdt_warnings kdt_options)
    target_compile_definitions(exr_seeds PRIVATE KDT_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
    message(STATUS "kdtrace: building the libFuzzer targets (ply, obj, cache, image, scene)")
  endif()
endif()
