# Smoke runs of the real executable: each asserts on exit status and output.
set(_kdt $<TARGET_FILE:kdtrace>)
set(_tmp ${CMAKE_BINARY_DIR}/smoke)
file(MAKE_DIRECTORY ${_tmp})

add_test(NAME smoke.scene_default COMMAND ${_kdt} scene -o ${_tmp}/default.json)
set_tests_properties(smoke.scene_default PROPERTIES
  PASS_REGULAR_EXPRESSION "scene default: 2 meshes, [0-9]+ vertices, 327682 triangles")

add_test(NAME smoke.scene_roundtrip COMMAND ${_kdt} scene ${_tmp}/default.json)
set_tests_properties(smoke.scene_roundtrip PROPERTIES DEPENDS smoke.scene_default
  PASS_REGULAR_EXPRESSION "327682 triangles")

add_test(NAME smoke.info_cube COMMAND ${_kdt} info /usr/share/assimp/models/PLY/cube.ply)
set_tests_properties(smoke.info_cube PROPERTIES PASS_REGULAR_EXPRESSION "triangles: +12")

add_test(NAME smoke.info_missing_file COMMAND ${_kdt} info ${_tmp}/does_not_exist.ply)
set_tests_properties(smoke.info_missing_file PROPERTIES WILL_FAIL FALSE
  PASS_REGULAR_EXPRESSION "does_not_exist.ply: cannot open")

add_test(NAME smoke.bad_flag COMMAND ${_kdt} scene --no-such-flag)
set_tests_properties(smoke.bad_flag PROPERTIES WILL_FAIL TRUE)
