# The viewer's tests (only when kdt_ui is built): kdt_ui_tests runs the real display path and
# one ImGui frame of every panel in an offscreen OSMesa GL 3.3 context (no GPU, no display),
# plus the pure parts (camera moves, heat scale); kdt_ui_e2e_tests runs the kdtrace executable
# under Xvfb (xvfb-run, scripts/setup.sh) and checks its screenshots and saved images.
# The background scene loader (no GL): in every preset, so it runs under ASan and TSan.
if(TARGET kdt_ui_render)
  add_executable(kdt_ui_loader_tests ${CMAKE_CURRENT_LIST_DIR}/scene_loader_test.cpp
                 ${CMAKE_CURRENT_SOURCE_DIR}/test_util.cpp)
  target_link_libraries(kdt_ui_loader_tests PRIVATE kdt_ui_render GTest::gtest GTest::gtest_main
                        kdt_warnings kdt_options)
  target_compile_definitions(kdt_ui_loader_tests PRIVATE KDT_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
                             KDT_BINARY_DIR="${CMAKE_BINARY_DIR}")
  gtest_discover_tests(kdt_ui_loader_tests DISCOVERY_TIMEOUT 60 PROPERTIES LABELS unit)
  add_dependencies(kdt_unit_tests kdt_ui_loader_tests)
endif()
if(NOT TARGET kdt_ui_core)
  return()
endif()
find_library(KDT_OSMESA_LIB OSMesa)
if(KDT_OSMESA_LIB)
  add_executable(kdt_ui_tests ${CMAKE_CURRENT_LIST_DIR}/display_test.cpp
                 ${CMAKE_CURRENT_LIST_DIR}/camera_control_test.cpp
                 ${CMAKE_CURRENT_LIST_DIR}/heat_map_test.cpp
                 ${CMAKE_CURRENT_LIST_DIR}/frame_pacer_test.cpp
                 ${CMAKE_CURRENT_LIST_DIR}/panels_test.cpp
                 ${CMAKE_CURRENT_LIST_DIR}/split_view_test.cpp
                 ${CMAKE_CURRENT_LIST_DIR}/viewer_files_test.cpp
                 ${CMAKE_CURRENT_LIST_DIR}/osmesa_context.cpp
                 ${CMAKE_CURRENT_LIST_DIR}/viewer_gui.cpp ${CMAKE_CURRENT_SOURCE_DIR}/test_util.cpp)
  target_link_libraries(kdt_ui_tests PRIVATE kdt_ui_core ${KDT_OSMESA_LIB} GTest::gtest
                        GTest::gtest_main kdt_warnings kdt_options)
  target_compile_definitions(kdt_ui_tests PRIVATE KDT_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
                             KDT_BINARY_DIR="${CMAKE_BINARY_DIR}")
  gtest_discover_tests(kdt_ui_tests DISCOVERY_TIMEOUT 60 PROPERTIES LABELS unit)
  add_dependencies(kdt_unit_tests kdt_ui_tests)
else()
  message(STATUS "kdtrace: libOSMesa not found (libosmesa6-dev): no offscreen display tests")
endif()
if(TARGET kdtrace)
  add_executable(kdt_ui_e2e_tests ${CMAKE_CURRENT_LIST_DIR}/e2e_test.cpp
                 ${CMAKE_CURRENT_SOURCE_DIR}/test_util.cpp)
  target_link_libraries(kdt_ui_e2e_tests PRIVATE kdt_renderer GTest::gtest GTest::gtest_main
                        kdt_warnings kdt_options)
  target_compile_definitions(kdt_ui_e2e_tests PRIVATE KDT_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
                             KDT_BINARY_DIR="${CMAKE_BINARY_DIR}" KDT_EXE="$<TARGET_FILE:kdtrace>")
  add_dependencies(kdt_ui_e2e_tests kdtrace)
  gtest_discover_tests(kdt_ui_e2e_tests DISCOVERY_TIMEOUT 60 PROPERTIES LABELS viewer)
endif()
