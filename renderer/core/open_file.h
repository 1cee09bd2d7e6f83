// Opening input files safely: only regular files, and never blocking on a FIFO.
// Depends on core/error.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace kdt {

/// What a file of this st_mode is when it is not a regular file ("a directory", "a FIFO
/// (pipe)", "a socket", "a character device", "a block device"); nullptr for a regular file.
const char* special_file_kind(uint32_t st_mode);

/// Why `name` cannot be a file name read from a JSON file: "file name contains a control
/// character (byte 0x00 at offset 7)" (a NUL would cut the name short at the system call,
/// "tri.ply\u0000.obj" opening tri.ply); empty when it has none.
std::string file_name_problem(const std::string& name);

/// `name` made absolute against the working directory (lexically normal, links kept), for
/// files named in sessions and image metadata, which are read from any directory; an empty
/// name (not given) stays empty, and a name the system cannot make absolute stays as it is.
std::string absolute_file_name(const std::string& name);

/// Whether two names denote one file: the same text, the same inode (links, `..`), or, for
/// a file that does not exist yet, the same path once made canonical.
bool same_file(const std::string& a, const std::string& b);

/// Opens path read-only (close-on-exec) and returns the descriptor. The file is opened
/// non-blocking, so a FIFO without a writer cannot hang the caller, and then checked: a
/// directory, FIFO, socket or device (/dev/zero would never end) is refused with an Error
/// naming the path and what it is; `what` names the expected kind ("a scene file", ...).
/// Reads on the returned descriptor block as usual. The caller closes it. `size`, when given,
/// receives the file's size.
int open_regular_file(const std::string& path, const char* what = "a file",
                      uint64_t* size = nullptr);

/// The whole of a regular file (opened as open_regular_file does). Files larger than
/// max_bytes are refused with an Error naming the path and the limit.
std::vector<uint8_t> read_regular_file(const std::string& path, uint64_t max_bytes,
                                       const char* what = "a file");

}  // namespace kdt
