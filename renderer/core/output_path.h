// Output paths that cannot destroy a command's inputs: the check every command that writes a
// file makes before it starts. Depends on core/error.h and core/temp_file.h.
#pragma once

#include <string>
#include <vector>

namespace kdt {

/// Throws kdt::Error naming `output` when writing it (a new file renamed over the path, or for
/// a symlink over the file it leads to: see write_target() in core/temp_file.h) could destroy
/// an input or cannot do what the user expects:
///  - `output` is the same file as one of `inputs`, however it is spelt: the same path, a
///    path through `..`, a symlink to it, a hard link (same device and inode) -- the
///    message names the input;
///  - `output` is (or is a symlink to) a directory, FIFO, socket or device: it would be
///    replaced by a regular file, or (written through) never end or hang;
///  - the directory that would hold it (for a dangling symlink, its target) does not exist,
///    or the symlinks loop;
///  - it (a symlink's target) exists and the user may not replace it: a regular file not
///    writable by the effective user (root may, as with `cp`), or another user's file in a
///    sticky directory such as /tmp (unless the user owns the directory or is root).
///  - the path, or a name in it, is longer than the system allows (path_length_problem()).
/// A missing output, or an existing regular file that is no input and may be replaced, is fine.
/// Inputs that do not exist (yet) are skipped; empty strings in `inputs` are ignored. `what` names
/// the output in messages ("the image", "the tree").
void check_output(const std::string& output, const std::vector<std::string>& inputs,
                  const char* what);

/// Why `path` is too long to create (the system would refuse it with ENAMETOOLONG), or an
/// empty string when it is not: the whole path is PATH_MAX bytes or more, or one of its names
/// is longer than a file name may be (NAME_MAX of the directory that would hold the file, or
/// 255 where that directory does not exist). The sentence gives the length and the limit.
std::string path_length_problem(const std::string& path);

}  // namespace kdt
