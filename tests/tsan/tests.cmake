# The viewer's threads under stress (render thread, tree rebuilds, UI-side setters): built in
# every preset; scripts/run_tsan.sh runs it under ThreadSanitizer (target kdt_ui_stress_tests).
add_executable(kdt_ui_stress_tests ${CMAKE_CURRENT_LIST_DIR}/viewer_stress_test.cpp
               ${CMAKE_CURRENT_SOURCE_DIR}/test_util.cpp)
target_link_libraries(kdt_ui_stress_tests PRIVATE kdt_ui_render GTest::gtest GTest::gtest_main
                      kdt_warnings kdt_options)
target_compile_definitions(kdt_ui_stress_tests PRIVATE KDT_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
                           KDT_BINARY_DIR="${CMAKE_BINARY_DIR}")
gtest_discover_tests(kdt_ui_stress_tests DISCOVERY_TIMEOUT 60 PROPERTIES LABELS unit)
add_dependencies(kdt_unit_tests kdt_ui_stress_tests)
