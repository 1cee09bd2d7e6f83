// Running another program from a bench (the MPI launcher, the plotting script) without a
// shell, so that file names reach it as they are. POSIX only (fork, execvp, waitpid).
#pragma once

#include <string>
#include <vector>

namespace kdt::app {

/// Runs argv (argv[0] looked up in PATH) and waits for it. Its stdout and stderr go to the
/// file `log` (created or truncated), or are this process's own when `log` is empty. No shell
/// reads the words: quotes, `$(...)` and blanks in them are plain characters. Returns the exit
/// status, or 128 + the signal, or 127 when the program could not be started; throws Error
/// when `log` cannot be written or no process can be made.
int run_program(const std::vector<std::string>& argv, const std::string& log = "");

}  // namespace kdt::app
