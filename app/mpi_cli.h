// `kdtrace render --mpi` and `--frames`: the flags of distributed and sequence renders and
// their driver. With MPI (KDT_HAVE_MPI) the tiles of a frame, or whole frames, are farmed
// out over the ranks of `mpirun` (renderer/dist); without it --frames renders every frame in
// this process and --mpi is an error.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "renderer/render/render_options.h"

namespace kdt::app {

struct DistArgs {
    bool mpi = false;                      ///< split over the ranks of mpirun
    std::string distribution = "dynamic";  ///< dynamic, interleaved or strips
    int batch = 0;                         ///< tiles per work message; 0 = threads per rank
    double timeout_seconds = 0.0;          ///< abort every rank after this long; 0 = none
    /// --frames: "N" (with --turntable), "views:A,B,..." or "views:all" (cameras of the
    /// --views file), "sessions:a.json,b.json,..." (session files); empty = one frame.
    std::string frames;
    bool turntable = false;  ///< the N frames orbit the camera about its up axis
    std::string stats_file;  ///< rank 0 writes per-rank stats as JSON here
    std::string throttle;    ///< test-only "RANK:FACTOR"
    std::string inject;      ///< test-only "RANK:FAULT" (--mpi-inject)
    /// Set by add_dist_options: the command whose flags a session frame re-applies, and the
    /// options its flags write into.
    CLI::App* command = nullptr;
    RenderOptions* command_options = nullptr;
};

/// Throws Error "<option> must be one of: dynamic, interleaved, strips (got '<text>')" unless
/// `text` names a work distribution (--distribution of render, --distributions of bench mpi).
void check_distribution_name(const std::string& option, const std::string& text);

/// Adds the flags to `app`, the render command, whose other flags (add_render_options) write
/// into `options`: --frames sessions: renders each session file with the command's flags.
void add_dist_options(CLI::App& app, DistArgs& args, RenderOptions& options);

/// The --mpi flags given on `app`'s command line without --mpi: a warning on stderr for
/// those that tune the farm (--distribution, --tile-batch, --timeout: the image is the same
/// without them), an error for those that ask for something only a farm does (--mpi-stats
/// would not be written; --throttle and --mpi-inject are test faults a test must not see
/// silently dropped).
void check_dist_flags(const CLI::App& app, const DistArgs& args);

/// The rank an MPI launcher gave this process, from the environment it sets before MPI_Init
/// (Open MPI's OMPI_COMM_WORLD_RANK, PMIx's PMIX_RANK, MPICH's PMI_RANK, Slurm's
/// SLURM_PROCID); -1 when no launcher started it.
int launcher_rank();

/// True for a process of `mpirun ... kdtrace ... --mpi` other than rank 0 (`argv` holds
/// "--mpi" and launcher_rank() > 0): it leaves what every rank would print before MPI starts
/// (an option error, a flag warning) to rank 0.
bool mpi_worker_before_init(int argc, const char* const* argv);

/// True when `render` runs through run_dist_render().
inline bool dist_requested(const DistArgs& args) {
    return args.mpi || !args.frames.empty() || args.turntable;
}

/// Renders `options` (resolved and validated) as the flags ask and writes `output`: for a
/// sequence a pattern with one printf integer conversion ("frame_%03d.png", the frame's
/// position from 0), or for views and sessions a name that gets "_<view name>" or
/// "_<session file stem>" before its extension. Every listed file is read, and every scene
/// loaded, before the first frame renders. Throws kdt::Error for bad input, and for --mpi in a
/// process no MPI launcher started (launcher_rank() < 0), before MPI_Init; with --mpi a
/// failure ends every rank with status 1, rank 0 printing the one message.
void run_dist_render(const RenderOptions& options, const std::string& output, bool quiet,
                     const DistArgs& args);

/// The camera of frame `frame` of `frames` of a turntable: `camera`'s eye rotated about the
/// axis through its target along its up vector, by 360 degrees x frame / frames.
CameraDesc turntable_camera(const CameraDesc& camera, int frame, int frames);

/// `pattern` with its one integer conversion (%d, %3d, %03d) replaced by `frame`; throws
/// kdt::Error naming the pattern when it has none, several or any other conversion.
std::string frame_path(const std::string& pattern, int frame);

/// The output of frame `frame` named `name` (empty for a turntable): frame_path() when
/// `output` has a '%', else `output` with "_<name>" before its extension. Throws kdt::Error
/// when a name is needed and empty or not a plain file name part ([A-Za-z0-9._+-]).
std::string frame_output(const std::string& output, int frame, const std::string& name);

}  // namespace kdt::app
