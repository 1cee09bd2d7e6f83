// The OBJ reader on lines longer than its block: binary data fails after one block with the
// message the whole line would give, long comments are dropped as they are read (line numbers
// stay right), and running out of memory names the file.
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/file_reader.h"
#include "renderer/io/obj_reader.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

const std::string kTri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
constexpr size_t kMiB = size_t(1) << 20;

// The error of reading `text` as t.obj (through a reader, so that what it read is known).
std::string error_of(const std::string& text, uint64_t* bytes_read = nullptr) {
    FileReader reader = FileReader::from_memory(text.data(), text.size(), "t.obj");
    std::string msg = test::error_of_call([&] { read_obj(reader); });
    if (bytes_read) *bytes_read = reader.bytes_read();
    return msg;
}

TEST(ObjLongLines, BinaryDataFailsAfterOneBlock) {
    uint64_t read = 0;
    const std::string msg = error_of(kTri + std::string(64 * kMiB, '\0'), &read);
    EXPECT_EQ(msg,
              "t.obj: line 5: not an OBJ statement: "
              "'\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00"
              "\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00"
              "\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00...' (binary data or UTF-16 text?)");
    EXPECT_LE(read, 2 * kMiB);  // not the 64 MiB line
}

TEST(ObjLongLines, NulInsideALongStatementFailsEarlyWithTheSameMessage) {
    std::string text = kTri + "vt " + std::string(3 * kMiB, '1') + std::string(1, '\0');
    text += std::string(61 * kMiB, '2') + "\n";
    uint64_t read = 0;
    EXPECT_EQ(error_of(text, &read),
              "t.obj: line 5: NUL byte in a statement (binary data or UTF-16 text?)");
    EXPECT_LE(read, 8 * kMiB);
    // A long line whose NUL is within the first block fails the same way.
    EXPECT_EQ(error_of(kTri + "o x" + std::string(1, '\0') + std::string(3 * kMiB, 'a')),
              "t.obj: line 5: NUL byte in a statement (binary data or UTF-16 text?)");
}

TEST(ObjLongLines, LongCommentsAreSkippedAndLinesCounted) {
    const std::string comment = "# " + std::string(5 * kMiB, 'x');
    // A comment ending in '\' does not continue: the next line is a statement.
    const std::string text = comment + "\n" + comment + "\\\n" + kTri + "f 1 2 x\n";
    EXPECT_EQ(error_of(text), "t.obj: line 7: face 2: invalid vertex index 'x'");
    const std::string good = "   " + comment + "\n" + kTri + comment;  // and one at the end
    TriangleMesh mesh = read_obj_memory(good.data(), good.size(), "t.obj");
    EXPECT_EQ(mesh.positions.size(), 3u);
    EXPECT_EQ(mesh.triangles.size(), 1u);
}

TEST(ObjLongLines, LongValidStatementsStillLoad) {
    // A polygon of 400k corners on one line (about 3 MiB), after a long 'o' statement.
    std::string text = "o " + std::string(2 * kMiB, 'n') + "\n" + kTri + "f";
    for (int i = 0; i < 400000; ++i) text += (i % 3 == 0) ? " 1" : (i % 3 == 1 ? " 2" : " 3");
    text += "\n";
    TriangleMesh mesh = read_obj_memory(text.data(), text.size(), "t.obj");
    EXPECT_EQ(mesh.triangles.size(), 1u + 399998u);
}

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define KDT_NO_ADDRESS_LIMIT 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define KDT_NO_ADDRESS_LIMIT 1
#endif
#endif

#ifndef KDT_NO_ADDRESS_LIMIT
// Caps the address space at 64 MiB above what the process uses, reads `text`, prints the
// error ("loaded" when none) and exits 0 (2 when the cap cannot be set). For a child
// process only.
[[noreturn]] void read_capped(const std::string& text) {
    long pages = 0;
    if (FILE* f = std::fopen("/proc/self/statm", "r")) {
        if (std::fscanf(f, "%ld", &pages) != 1) pages = 0;
        std::fclose(f);
    }
    const rlim_t limit = rlim_t(pages) * rlim_t(::sysconf(_SC_PAGESIZE)) + 64 * kMiB;
    const rlimit cap{limit, limit};
    if (pages == 0 || ::setrlimit(RLIMIT_AS, &cap) != 0) std::_Exit(2);
    const std::string msg = error_of(text);
    std::fprintf(stderr, "%s\n", msg.empty() ? "loaded" : msg.c_str());
    std::_Exit(0);
}
#endif

// In a child process whose address space is capped a little above what it uses: a 160 MiB
// statement cannot be held, and the error names the file instead of a bare "out of memory";
// a comment as long costs no memory.
TEST(ObjLongLines, OutOfMemoryNamesTheFile) {
#ifdef KDT_NO_ADDRESS_LIMIT
    GTEST_SKIP() << "sanitizers reserve more address space than any limit allows";
#else
    GTEST_FLAG_SET(death_test_style, "fast");
    const std::string text = kTri + "vt " + std::string(160 * kMiB, '1') + "\n";
    EXPECT_EXIT(read_capped(text), ::testing::ExitedWithCode(0),
                "^t.obj: out of memory reading the mesh\n$");
    // A comment as long is dropped as it is read: it loads under the same cap.
    const std::string comment = "# " + std::string(160 * kMiB, 'c') + "\n" + kTri;
    EXPECT_EXIT(read_capped(comment), ::testing::ExitedWithCode(0), "^loaded\n$");
#endif
}

}  // namespace
}  // namespace kdt
