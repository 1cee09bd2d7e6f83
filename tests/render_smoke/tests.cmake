# Smoke runs of `kdtrace render` and `kdtrace bench converge` on a tiny model: exit status,
# summary line, output files, and bad flags. (The path tracer's owner; see tests/app for the rest.)
set(_kdt $<TARGET_FILE:kdtrace>)
set(_tmp ${CMAKE_BINARY_DIR}/smoke_render)
file(MAKE_DIRECTORY ${_tmp})
set(_cube /usr/share/assimp/models/PLY/cube.ply)

if(EXISTS ${_cube})
  foreach(_ext png exr pfm)
    add_test(NAME smoke.render_cube_${_ext}
             COMMAND ${_kdt} render ${_cube} --no-cache --width 32 --height 24 --spp 2 --quiet
                     -o ${_tmp}/cube.${_ext})
    set_tests_properties(smoke.render_cube_${_ext} PROPERTIES
      PASS_REGULAR_EXPRESSION "render: .*cube.ply: 32x24, .* 2.0 spp, .* Mrays/s .* -> .*cube.${_ext}")
  endforeach()
  add_test(NAME smoke.render_cube_adaptive_error
           COMMAND ${_kdt} render ${_cube} --no-cache --width 16 --height 16 --error 0.2
                   --light-sampling nee --filter tent --quiet -o ${_tmp}/cube_err.pfm)
  set_tests_properties(smoke.render_cube_adaptive_error PROPERTIES
    PASS_REGULAR_EXPRESSION "est. rel. error 0\\.[01]")
  add_test(NAME smoke.render_bad_light_sampling
           COMMAND ${_kdt} render ${_cube} --light-sampling sometimes -o ${_tmp}/x.png)
  set_tests_properties(smoke.render_bad_light_sampling PROPERTIES
    PASS_REGULAR_EXPRESSION "--light-sampling must be one of: bsdf, nee, mis \\(got 'sometimes'\\)")
  add_test(NAME smoke.render_bad_extension
           COMMAND ${_kdt} render ${_cube} --no-cache --width 8 --height 8 --spp 1 -o ${_tmp}/x.bmp)
  set_tests_properties(smoke.render_bad_extension PROPERTIES
    PASS_REGULAR_EXPRESSION "x.bmp: unknown image format .\.bmp.")
  # A missing output directory or a bad stop condition fails before the tree is built.
  add_test(NAME smoke.render_missing_output_dir
           COMMAND ${_kdt} render ${_cube} --width 8 --height 8 --spp 1
                   --cache-dir ${_tmp}/fail_fast_cache -o ${_tmp}/no_such_dir/x.png)
  set_tests_properties(smoke.render_missing_output_dir PROPERTIES
    PASS_REGULAR_EXPRESSION "no_such_dir/x.png: no directory [^\n]*no_such_dir to write into"
    FAIL_REGULAR_EXPRESSION "kd-tree cache")
  add_test(NAME smoke.render_negative_spp
           COMMAND ${_kdt} render ${_cube} --width 8 --height 8 --spp -2
                   --cache-dir ${_tmp}/fail_fast_cache -o ${_tmp}/x.png)
  set_tests_properties(smoke.render_negative_spp PROPERTIES
    PASS_REGULAR_EXPRESSION "--spp must be in \\(0, 1073741824\\] \\(got -2\\)"
    FAIL_REGULAR_EXPRESSION "kd-tree cache")
  # --view takes the camera from the views file; the metadata records the view's eye.
  add_test(NAME smoke.render_cube_view
           COMMAND ${_kdt} render ${_cube} --no-cache --width 8 --height 6 --spp 1 --view B
                   --views ${CMAKE_SOURCE_DIR}/assets/views/dragon.json -o ${_tmp}/view.pfm)
  set_tests_properties(smoke.render_cube_view PROPERTIES
    PASS_REGULAR_EXPRESSION "render: .*cube.ply: 8x6, .* -> .*view.pfm")
  add_test(NAME smoke.render_unknown_view
           COMMAND ${_kdt} render ${_cube} --no-cache --view Z
                   --views ${CMAKE_SOURCE_DIR}/assets/views/dragon.json -o ${_tmp}/x.png)
  set_tests_properties(smoke.render_unknown_view PROPERTIES
    PASS_REGULAR_EXPRESSION "dragon.json: no view named .Z. \\(views: A, B, C, D\\)")
  add_test(NAME smoke.bench_converge_cube
           COMMAND ${_kdt} bench converge ${_cube} --width 16 --height 12 --reference-spp 64
                   --max-spp 4 --no-plot --no-cache -o ${_tmp}/converge)
  set_tests_properties(smoke.bench_converge_cube PROPERTIES
    PASS_REGULAR_EXPRESSION "equal time .* RMSE ratio against uniform")
endif()
