// The OBJ reader on lines longer than its block: binary data fails after one block with the
// message the whole line would give, long comments and statements are read in pieces without
// holding them (results and line numbers as for short ones, also with CR line ends split
// between blocks), and running out of memory names the file.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

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

// The mesh of `text` read as t.obj.
TriangleMesh load(const std::string& text) {
    return read_obj_memory(text.data(), text.size(), "t.obj");
}

// Long statements read in pieces give what their short forms give: blanks, trailing comments
// (with continued lines) and skipped statements are dropped, values and corners kept.
TEST(ObjLongLines, LongStatementsReadAsShortOnes) {
    const std::string pad(3 * kMiB, ' ');
    const std::string comment = " # " + std::string(3 * kMiB, 'c');
    const std::string tag(3 * kMiB, 'n');
    struct Case {
        std::string long_text, short_text;
    };
    const std::vector<Case> cases = {
        {"v 0" + pad + "0 0\nv 1 0 0" + comment + "\nv 0 1" + pad + "\\\n0\nf 1 2 3\n",
         "v 0 0 0\nv 1 0 0\nv 0 1\\\n0\nf 1 2 3\n"},
        {"vn 0 0" + pad + "1\n" + kTri + "f 1//1" + pad + "2//1 3//1" + comment + "\\\n4\n",
         "vn 0 0 1\n" + kTri + "f 1//1 2//1 3//1\n\n"},
        {"vt " + pad + "0 0\r" + kTri + "o " + tag + "\r\ng " + tag + "\\\r\nvt 1 1\rs " + tag +
             "\nusemtl " + tag + "\rmtllib " + tag + "\r\nf 1 2 3\r",
         "vt 0 0\r" + kTri + "o x\r\ng x\\\r\nvt 1 1\rs 1\nusemtl x\rmtllib x\r\nf 1 2 3\r"},
        // A keyword of over 40 bytes, a line of blanks, a BOM before a long first line.
        {std::string("\xef\xbb\xbfv") + pad + "0 0 0\n" + std::string(2 * kMiB, 'v') + " 1\n" +
             pad + "\nv 1 0 0\nv 0 1 0\nf" + pad + "1 2 3",
         "\xef\xbb\xbfv 0 0 0\nvvvv 1\n\nv 1 0 0\nv 0 1 0\nf 1 2 3"},
    };
    for (const Case& c : cases) {
        const TriangleMesh a = load(c.long_text), b = load(c.short_text);
        EXPECT_EQ(a.positions, b.positions);
        EXPECT_EQ(a.triangles, b.triangles);
        EXPECT_GE(a.triangle_count(), 1u);
        // Line numbers are counted as for the short form: an error on the next line.
        const std::string bad = "v 1 2\n";
        EXPECT_EQ(error_of(c.long_text + "\n" + bad), error_of(c.short_text + "\n" + bad));
    }
    // Errors inside a long statement name its line and element.
    EXPECT_EQ(error_of(kTri + "v 1" + pad + "2\n"),
              "t.obj: line 5: vertex 4: has 2 coordinates (x y z needed)");
    EXPECT_EQ(error_of(kTri + "v 1" + pad + "2 3 4 5 6 7 8\n"),
              "t.obj: line 5: vertex 4: more than 7 values (x y z [w] or x y z r g b [a])");
    EXPECT_EQ(error_of(kTri + "f 1" + pad + "2 0\n"),
              "t.obj: line 5: face 2: vertex index 0 (OBJ indices start at 1)");
    EXPECT_EQ(error_of(kTri + "vn" + pad + "\\\n 0 0\n"),
              "t.obj: line 5: normal 1: has 2 values (x y z needed)");
    EXPECT_EQ(error_of(kTri + "f 1 2 3" + pad + std::string(1, '\0') + "\n"),
              "t.obj: line 5: NUL byte in a statement (binary data or UTF-16 text?)");
    EXPECT_EQ(error_of(kTri + "o x" + pad + std::string(1, '\0') + "\n"),
              "t.obj: line 5: NUL byte in a statement (binary data or UTF-16 text?)");
    EXPECT_EQ(error_of(pad + "\x01" + pad),
              "t.obj: line 1: not an OBJ statement: '\\x01' "
              "(binary data or UTF-16 text?)");
    // A '\' ending the data continues a long statement onto nothing, as a short one.
    EXPECT_EQ(load(kTri + "f 1 2" + pad + "3\\").triangle_count(), 2u);
    EXPECT_EQ(error_of(kTri + "v" + pad + "\\"),
              "t.obj: line 5: vertex 4: has 0 coordinates (x y z needed)");
    // A value or corner is held whole; one of a block or more is refused.
    EXPECT_EQ(error_of(kTri + "v 1 2 " + std::string(2 * kMiB, '3') + "\n"),
              "t.obj: line 5: vertex 4: value '3333333333333333333333333333333333333333...' "
              "longer than 1 MiB");
    EXPECT_EQ(error_of(kTri + "f 1 2 " + std::string(2 * kMiB, '3') + "\n"),
              "t.obj: line 5: face 2: corner '3333333333333333333333333333333333333333...' "
              "longer than 1 MiB");
}

// The error of reading `text` with blocks of `block` bytes (obj::set_block_bytes).
std::string error_with_block(const std::string& text, size_t block) {
    const size_t old = obj::set_block_bytes(block);
    std::string msg = error_of(text);
    obj::set_block_bytes(old);
    return msg;
}

// A value or corner is refused from kMaxTokenBytes (1 MiB) on, exactly, wherever it ends
// relative to a block end, whatever the block size: one of 1 MiB - 2 bytes ending at or just
// before a block end was refused with the default block (the 2 bytes of look-ahead after it
// were counted), and accepted with a block of 3 bytes.
TEST(ObjLongLines, ValuesUpTo1MiBLoadAtAnyBlockEnd) {
    for (const size_t len : {kMiB - 3, kMiB - 2, kMiB - 1, kMiB}) {
        for (const std::string kind : {"f", "v"}) {
            for (int shift = -3; shift <= 3; ++shift) {
                // The corner (an index 3) or value (0) ends `shift` bytes from the end of the
                // second block.
                const std::string head = kTri + kind + " 1 2 ";
                std::string text(head);
                text.append(2 * kMiB + size_t(shift) - len - head.size(), ' ');
                text.append(len - 1, '0');
                text += kind == "f" ? "3" : "0";
                ASSERT_EQ(text.size(), 2 * kMiB + size_t(shift));
                text += "\nv 0 0 0\nv x\n";
                const std::string accepted = "t.obj: line 7: vertex " +
                                             std::string(kind == "f" ? "5" : "6") +
                                             ": invalid number 'x'";
                const std::string refused =
                    "t.obj: line 5: " +
                    std::string(kind == "f" ? "face 2: corner" : "vertex 4: value") +
                    " '0000000000000000000000000000000000000000...' longer than 1 MiB";
                for (const size_t block : {kMiB, size_t(1), size_t(3), kMiB / 2}) {
                    EXPECT_EQ(error_with_block(text, block), len < kMiB ? accepted : refused)
                        << kind << " " << len << " " << shift << " block " << block;
                }
            }
        }
    }
    // A line read whole (not in pieces), from a buffer grown past a block by a long value: a
    // long comment is dropped from the buffer, which then holds all of the next line.
    const std::string grown =
        kTri + "v 0 0 " + std::string(kMiB - 2, '0') + "\n#" + std::string(kMiB + 100, 'c') + "\n";
    EXPECT_EQ(error_of(grown + "f 1 2 " + std::string(kMiB + 5, '0') + "3\n"),
              "t.obj: line 7: face 2: corner '0000000000000000000000000000000000000000...' "
              "longer than 1 MiB");
}

// A line end split between two blocks: CRLF read as one line end, CR alone as one, after
// short lines, long comments and long statements alike (a continued one in `vt`).
TEST(ObjLongLines, LineEndsBetweenBlocks) {
    struct Kind {
        std::string name;
        int line, vertex;  // of the "v x" that ends the text
    };
    for (const std::string eol : {"\r\n", "\r", "\n"}) {
        for (const Kind& k :
             {Kind{"short", 9, 5}, Kind{"comment", 8, 4}, Kind{"vt", 8, 4}, Kind{"f", 12, 7}}) {
            for (int shift = -3; shift <= 3; ++shift) {
                // The line end starts `shift` bytes from the end of the first or second block.
                const size_t at = (k.name == "short" ? 1 : 2) * kMiB + size_t(shift);
                std::string text;
                if (k.name == "short") text = std::string(at - 8, '#') + "\nv 0 0 0";
                if (k.name == "comment") text = "#" + std::string(at - 1, 'c');
                if (k.name == "vt") text = "vt 0 0" + std::string(at - 7, ' ') + "\\";
                if (k.name == "f") text = kTri + "f 1 2 3" + std::string(at - kTri.size() - 7, ' ');
                ASSERT_EQ(text.size(), at);
                text += eol + "#x\n" + kTri + "f 1 2 3" + eol + "v x";
                EXPECT_EQ(error_of(text), "t.obj: line " + std::to_string(k.line) + ": vertex " +
                                              std::to_string(k.vertex) + ": invalid number 'x'")
                    << k.name << " " << printable(eol) << " " << shift;
            }
        }
    }
}

#ifndef KDT_NO_ADDRESS_LIMIT
// Reads `text` under test::run_capped() with 64 MiB to spare, printing the error (or "loaded V
// vertices, T triangles"). For a child process only.
[[noreturn]] void read_capped(const std::string& text) {
    test::run_capped(64 * kMiB, [&] {
        const TriangleMesh mesh = load(text);
        std::fprintf(stderr, "loaded %zu vertices, %zu triangles\n", size_t(mesh.vertex_count()),
                     size_t(mesh.triangle_count()));
    });
}
#endif

// In a child process whose address space is capped a little above what it uses: running out
// of memory names the file instead of a bare "out of memory" (a polygon of 80 M corners holds
// 320 MiB of indices), while statements and comments of 96 to 200 MiB, and a file of CR-only
// line ends longer than the cap, load: they are never held whole.
TEST(ObjLongLines, LongLinesAreNotHeld) {
#ifdef KDT_NO_ADDRESS_LIMIT
    GTEST_SKIP() << "sanitizers reserve more address space than any limit allows";
#else
    GTEST_FLAG_SET(death_test_style, "fast");
    std::string face = kTri + "f";
    face.resize(face.size() + 160 * kMiB, ' ');
    for (size_t i = kTri.size() + 2; i < face.size(); i += 2) face[i] = '1';
    face += "\n";
    EXPECT_EXIT(read_capped(face), ::testing::ExitedWithCode(0),
                "^t.obj: out of memory reading the mesh\n$");
    // A 200 MiB `vt` line, then 96 MiB ones (holding one would take a 128 MiB buffer), built
    // in one string so that the test stays fast.
    std::string& text = face;
    const std::string loaded = "^loaded 3 vertices, 1 triangles\n$";
    auto make = [&text](const std::string& head, size_t blanks,
                        const std::string& tail) -> const std::string& {
        text.assign(head);
        text.append(blanks, ' ');
        text += tail;
        return text;
    };
    EXPECT_EXIT(read_capped(make("vt", 200 * kMiB, "1 2 3\n" + kTri)), ::testing::ExitedWithCode(0),
                loaded);
    for (const char* keyword : {"#", "vn", "o", "g", "s", "usemtl", "mtllib"}) {
        EXPECT_EXIT(read_capped(make(keyword, 96 * kMiB, "1 2 3\n" + kTri)),
                    ::testing::ExitedWithCode(0), loaded)
            << keyword;
    }
    EXPECT_EXIT(read_capped(make(kTri + "f 1", 96 * kMiB, "2 3 # " + std::string(kMiB, 'c'))),
                ::testing::ExitedWithCode(0), "^loaded 3 vertices, 2 triangles\n$");
    EXPECT_EXIT(read_capped(make(kTri + "v 1 2 3 #", 96 * kMiB, "\n")),
                ::testing::ExitedWithCode(0), "^loaded 4 vertices, 1 triangles\n$");
    // 100 MiB of CR-only lines: before CR ended a line, all of it was one line.
    std::string& cr = text;
    cr = "v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r";
    for (const std::string vt = "vt 0.125 0.25\r"; cr.size() < 100 * kMiB;) cr += vt;
    EXPECT_EXIT(read_capped(cr), ::testing::ExitedWithCode(0), loaded);
#endif
}

}  // namespace
}  // namespace kdt
