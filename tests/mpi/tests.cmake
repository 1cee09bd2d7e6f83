# MPI runs of `kdtrace render --mpi` and `--frames` on this machine (tests/mpi/mpi_test.sh):
# bitwise identity with the single-process render, dynamic balancing, failing ranks.
# Registered only with KDT_WITH_MPI; a case skips (exit 77) when mpiexec is missing.
if(KDT_WITH_MPI AND EXISTS /usr/share/assimp/models/PLY/Wuson.ply)
  set(_mpiexec ${MPIEXEC_EXECUTABLE})
  if(NOT _mpiexec)
    set(_mpiexec mpirun)
  endif()
  foreach(_case identity_dynamic identity_interleaved identity_strips frames throttle fail_load
                fail_hash fail_missing timeout refuse_adaptive views sessions adaptive_frames
                bad_list stats_output timeout_stall timeout_stop rescue test_flags
                env_mismatch bench_quote bench_no_baseline option_error interrupt
                interrupt_worker frames_session worker_warnings bad_result bad_work bad_options
                bad_log orphan
                frames_passes
                threads_default frames_names camera_errors)
    add_test(NAME mpi.${_case}
             COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/mpi_test.sh ${_case} $<TARGET_FILE:kdtrace>
                     ${_mpiexec} ${CMAKE_BINARY_DIR}/mpi_tests/${_case}
                     /usr/share/assimp/models/PLY/Wuson.ply)
    set_tests_properties(mpi.${_case} PROPERTIES TIMEOUT 120 SKIP_RETURN_CODE 77 LABELS mpi)
  endforeach()
endif()

# --mpi outside mpirun is one line and status 1 before MPI_Init, not Open MPI's singleton
# start-up, which fails in 40 lines without ssh or rsh on PATH.
if(KDT_WITH_MPI)
  kdt_status_test(smoke.mpi_without_mpirun 1
    "^kdtrace: error: --mpi: not started by mpirun \\(run it as `mpirun -np N kdtrace render[^\n]*\n$"
    env -u OMPI_COMM_WORLD_RANK -u PMIX_RANK -u PMI_RANK -u SLURM_PROCID
    PATH=/nonexistent $<TARGET_FILE:kdtrace> render --mpi --spp 1 --width 8
    --height 6 --quiet -o ${CMAKE_BINARY_DIR}/mpi_without_mpirun.pfm)
endif()

# --frames without MPI: bad output patterns and a sequence without a kind are errors.
set(_cube /usr/share/assimp/models/PLY/cube.ply)
if(EXISTS ${_cube})
  kdt_status_test(smoke.frames_bad_pattern 1
    "frame.png: a --frames output needs exactly one frame number conversion"
    $<TARGET_FILE:kdtrace> render ${_cube} --no-cache --width 8 --height 8 --spp 1
    --frames 3 --turntable -o ${CMAKE_BINARY_DIR}/frame.png)
  kdt_status_test(smoke.frames_need_turntable 1 "--frames N needs --turntable"
    $<TARGET_FILE:kdtrace> render ${_cube} --no-cache --frames 3
    -o ${CMAKE_BINARY_DIR}/frame_%d.png)
  kdt_status_test(smoke.turntable_needs_frames 1 "--turntable needs --frames N"
    $<TARGET_FILE:kdtrace> render ${_cube} --no-cache --turntable
    -o ${CMAKE_BINARY_DIR}/frame_%d.png)
endif()
