# The viewer's tests (only when kdt_ui is built): kdt_ui_tests runs the real display path and
# one ImGui frame of every panel in an offscreen OSMesa GL 3.3 context (no GPU, no display),
# plus the pure parts (camera moves, heat scale); kdt_ui_e2e_tests runs the kdtrace executable
# under Xvfb (xvfb-run, scripts/setup.sh) and checks its screenshots and saved images.

# A gtest executable `name` of the files `ARGN` (in this directory) and test_util.cpp, linked
# with `lib`, its tests labelled `label`.
function(kdt_ui_gtest name lib label)
  list(TRANSFORM ARGN PREPEND ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/)
  add_executable(${name} ${ARGN} ${CMAKE_CURRENT_SOURCE_DIR}/test_util.cpp)
  target_link_libraries(${name} PRIVATE ${lib} GTest::gtest GTest::gtest_main kdt_warnings
                        kdt_options)
  target_compile_definitions(${name} PRIVATE KDT_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
                             KDT_BINARY_DIR="${CMAKE_BINARY_DIR}")
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES LABELS ${label})
endfunction()
# The background scene loader, and the viewer's threads under stress (render thread, tree
# rebuilds, UI-side setters; source beside the TSan suppressions): no GL, in every preset, so
# they run under ASan and TSan (scripts/run_tsan.sh).
if(TARGET kdt_ui_render)
  kdt_ui_gtest(kdt_ui_loader_tests kdt_ui_render unit scene_loader_test.cpp)
  kdt_ui_gtest(kdt_ui_stress_tests kdt_ui_render unit ../tsan/viewer_stress_test.cpp)
  add_dependencies(kdt_unit_tests kdt_ui_loader_tests kdt_ui_stress_tests)
endif()
if(NOT TARGET kdt_ui_core)
  return()
endif()
find_library(KDT_OSMESA_LIB OSMesa)
if(KDT_OSMESA_LIB)
  kdt_ui_gtest(kdt_ui_tests "kdt_ui_core;${KDT_OSMESA_LIB}" unit display_test.cpp
               camera_control_test.cpp heat_map_test.cpp frame_pacer_test.cpp panels_test.cpp
               split_view_test.cpp viewer_files_test.cpp osmesa_context.cpp viewer_gui.cpp)
  add_dependencies(kdt_unit_tests kdt_ui_tests)
else()
  message(STATUS "kdtrace: libOSMesa not found (libosmesa6-dev): no offscreen display tests")
endif()
if(TARGET kdtrace)
  kdt_ui_gtest(kdt_ui_e2e_tests kdt_renderer viewer e2e_test.cpp)
  target_compile_definitions(kdt_ui_e2e_tests PRIVATE KDT_EXE="$<TARGET_FILE:kdtrace>")
  add_dependencies(kdt_ui_e2e_tests kdtrace)
endif()
