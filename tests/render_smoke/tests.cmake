# Smoke runs of `kdtrace render` and `kdtrace bench converge` on a tiny model: exit status,
# summary line, output files, and bad flags. (The path tracer's owner; see tests/app for the rest.)
set(_kdt $<TARGET_FILE:kdtrace>)
set(_tmp ${CMAKE_BINARY_DIR}/smoke_render)
file(MAKE_DIRECTORY ${_tmp})
set(_cube /usr/share/assimp/models/PLY/cube.ply)

if(EXISTS ${_cube})
  foreach(_ext png exr pfm)
    kdt_status_test(smoke.render_cube_${_ext} 0
      "render: .*cube.ply: 32x24, .* 2.0 spp, .* Mrays/s .* -> .*cube.${_ext}"
      ${_kdt} render ${_cube} --no-cache --width 32 --height 24 --spp 2 --quiet
      -o ${_tmp}/cube.${_ext})
  endforeach()
  kdt_status_test(smoke.render_cube_adaptive_error 0 "est. rel. error 0\\.[01]"
    ${_kdt} render ${_cube} --no-cache --width 16 --height 16 --error 0.2
    --light-sampling nee --filter tent --quiet -o ${_tmp}/cube_err.pfm)
  kdt_status_test(smoke.render_bad_light_sampling 1
    "--light-sampling must be one of: bsdf, nee, mis \\(got 'sometimes'\\)"
    ${_kdt} render ${_cube} --light-sampling sometimes -o ${_tmp}/x.png)
  kdt_status_test(smoke.render_bad_extension 1 "x.bmp: unknown image format .\\.bmp."
    ${_kdt} render ${_cube} --no-cache --width 8 --height 8 --spp 1 -o ${_tmp}/x.bmp)
  # A missing output directory or a bad stop condition fails before the tree is built.
  kdt_status_test(smoke.render_missing_output_dir 1
    "no_such_dir/x.png: no directory [^\n]*no_such_dir to write into"
    ${_kdt} render ${_cube} --width 8 --height 8 --spp 1
    --cache-dir ${_tmp}/fail_fast_cache -o ${_tmp}/no_such_dir/x.png)
  set_tests_properties(smoke.render_missing_output_dir PROPERTIES
    FAIL_REGULAR_EXPRESSION "kd-tree cache")
  kdt_status_test(smoke.render_negative_spp 1 "--spp must be in \\(0, 1073741824\\] \\(got -2\\)"
    ${_kdt} render ${_cube} --width 8 --height 8 --spp -2
    --cache-dir ${_tmp}/fail_fast_cache -o ${_tmp}/x.png)
  set_tests_properties(smoke.render_negative_spp PROPERTIES
    FAIL_REGULAR_EXPRESSION "kd-tree cache")
  # --view takes the camera from the views file; the metadata records the view's eye.
  kdt_status_test(smoke.render_cube_view 0 "render: .*cube.ply: 8x6, .* -> .*view.pfm"
    ${_kdt} render ${_cube} --no-cache --width 8 --height 6 --spp 1 --view B
    --views ${CMAKE_SOURCE_DIR}/assets/views/dragon.json -o ${_tmp}/view.pfm)
  kdt_status_test(smoke.render_unknown_view 1
    "dragon.json: no view named .Z. \\(views: A, B, C, D\\)"
    ${_kdt} render ${_cube} --no-cache --view Z
    --views ${CMAKE_SOURCE_DIR}/assets/views/dragon.json -o ${_tmp}/x.png)
  kdt_status_test(smoke.bench_converge_cube 0 "equal time .* RMSE ratio against uniform"
    ${_kdt} bench converge ${_cube} --width 16 --height 12 --reference-spp 64
    --max-spp 4 --no-plot --no-cache -o ${_tmp}/converge)
endif()
