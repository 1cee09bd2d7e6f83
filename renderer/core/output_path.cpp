#include "renderer/core/output_path.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstring>
#include <filesystem>

#include "renderer/core/error.h"
#include "renderer/core/open_file.h"
#include "renderer/core/temp_file.h"

namespace kdt {

namespace fs = std::filesystem;

void check_output(const std::string& output, const std::vector<std::string>& inputs,
                  const char* what) {
    auto fail = [&](const std::string& message) {
        throw Error(ErrorLocation{output}, std::string("cannot write ") + what + ": " + message);
    };
    if (output.empty()) throw Error(std::string("no file name given for ") + what);
    struct stat link {};
    if (::lstat(output.c_str(), &link) != 0) {
        if (errno == ENAMETOOLONG) {
            const std::string why = path_length_problem(output);
            fail(why.empty() ? std::string("cannot stat: ") + std::strerror(ENAMETOOLONG) : why);
        }
        if (errno != ENOENT) fail(std::string("cannot stat: ") + std::strerror(errno));
        // A new file: its directory must exist (checked now, not after a long run).
        std::error_code ec;
        const fs::path dir = fs::absolute(output, ec).parent_path();
        if (!fs::is_directory(dir, ec)) fail("directory " + dir.string() + " does not exist");
        TempFile probe(output);  // a directory that takes no new file (read-only, /proc)
        return;
    }
    // A symlink is written through (see write_target()): what counts is the file at the end
    // of its chain, which a dangling link names too.
    const bool is_link = S_ISLNK(link.st_mode);
    const std::string real = is_link ? write_target(output) : output;
    struct stat target {};
    const bool resolves = ::stat(real.c_str(), &target) == 0;
    if (resolves) {
        if (const char* kind = special_file_kind(target.st_mode)) {
            fail(std::string(is_link ? "is a symlink to " : "is ") + kind +
                 (S_ISDIR(target.st_mode)
                      ? " (give a file name)"
                      : ", not a regular file (refusing to replace it or to write into it)"));
        }
    } else if (is_link) {
        std::error_code ec;
        const fs::path dir = fs::absolute(real, ec).parent_path();
        if (!fs::is_directory(dir, ec)) {
            fail("is a dangling symlink to " + real + ", whose directory " + dir.string() +
                 " does not exist");
        }
    }
    for (const std::string& input : inputs) {
        if (input.empty()) continue;
        struct stat in {};
        if (::stat(input.c_str(), &in) != 0) continue;
        // stat() follows symlinks on both sides, so this catches a symlink either way round,
        // a hard link, `..` and any other spelling of the same file.
        if (resolves && target.st_dev == in.st_dev && target.st_ino == in.st_ino) {
            fail("it is the input " + input +
                 (output == input ? "" : " (the same file by another path or link)") +
                 "; writing it would destroy the input");
        }
    }
    // An existing file is replaced by a rename into place, which its own mode does not stop:
    // honour a write-protected file as `cp` and the shell's `>` do (root may, as with cp).
    if (resolves && ::faccessat(AT_FDCWD, real.c_str(), W_OK, AT_EACCESS) != 0) {
        fail(std::string(is_link ? "the symlink's target " + real : "the existing file") +
             " is not writable (" + std::strerror(errno) + "); refusing to replace it");
    }
    // In a sticky directory (like /tmp) only the file's owner, the directory's owner or root
    // may replace it; the rename would fail only after the work.
    const uid_t me = ::geteuid();
    fs::path dir = fs::path(real).parent_path();
    if (dir.empty()) dir = ".";
    struct stat d {};
    if (me != 0 && resolves && target.st_uid != me && ::stat(dir.c_str(), &d) == 0 &&
        (d.st_mode & S_ISVTX) && d.st_uid != me) {
        fail("it belongs to another user (uid " + std::to_string(target.st_uid) +
             ") in the sticky directory " + dir.string() +
             ", where only its owner may replace it; choose another name");
    }
    // The output is written as a temporary file renamed over it: one must be creatable.
    TempFile probe(output);
}

std::string path_length_problem(const std::string& path) {
    if (path.size() >= PATH_MAX) {
        return "path too long: " + std::to_string(path.size()) + " bytes, more than the " +
               std::to_string(PATH_MAX - 1) + " a path may have";
    }
    const fs::path whole(path);
    fs::path dir = whole.parent_path();
    if (dir.empty()) dir = ".";
    // The limit is the filesystem's; where the directory is missing (the caller says so when
    // the names fit), the usual one.
    long name_max = ::pathconf(dir.c_str(), _PC_NAME_MAX);
    if (name_max <= 0) name_max = NAME_MAX;
    const std::string limit = std::to_string(name_max) + " bytes a file name may have";
    for (const fs::path& part : whole.parent_path()) {
        const std::string name = part.string();
        if (long(name.size()) > name_max) {
            // excerpt() adds the length: the name is longer than the 40 bytes shown.
            return "file name too long: the directory name " + excerpt(name, 40) +
                   " is more than the " + limit;
        }
    }
    const std::string name = whole.filename().string();
    if (long(name.size()) > name_max) {
        return "file name too long: " + std::to_string(name.size()) + " bytes, more than the " +
               limit;
    }
    return "";
}

}  // namespace kdt
