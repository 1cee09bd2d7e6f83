// Tests of the OBJ reader's messages (renderer/io/obj_reader): hostile bytes in echoed
// tokens come out escaped and never cut the message short; faces of fewer than three
// indices say so.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/obj_reader.h"

namespace kdt {
namespace {

std::string error_of(const std::string& text) {
    try {
        read_obj_memory(text.data(), text.size(), "m.obj");
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

TEST(ObjMessages, HostileTokensAreEscaped) {
    const std::vector<std::string> tokens = {"1\x1b[2J", "2\x07",     std::string("3\0x", 3),
                                             "4\xff",    "5\xc2\x9b", "6\xe2\x80\xae"};
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    for (const std::string& token : tokens) {
        for (const std::string& file : {"v 1 2 " + token + "\n", tri + "vn 0 0 " + token + "\n",
                                        tri + "f 1 2 " + token + "\n"}) {
            SCOPED_TRACE(printable(file));
            const std::string msg = error_of(file);
            ASSERT_FALSE(msg.empty());
            for (char c : msg)
                EXPECT_TRUE(static_cast<unsigned char>(c) >= 0x20 &&
                            static_cast<unsigned char>(c) < 0x7f)
                    << printable(msg);
            // A NUL is refused as such before any token is echoed.
            const bool nul = token.find('\0') != std::string::npos;
            EXPECT_NE(msg.find(nul ? "NUL byte in a statement" : printable(token)),
                      std::string::npos)
                << msg;
        }
    }
}

TEST(ObjMessages, FacesOfFewerThanThreeIndicesSaySo) {
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    EXPECT_NE(error_of(tri + "f 1 2\n").find("line 5: face 2: 2 indices, a face needs at least 3"),
              std::string::npos);
    EXPECT_NE(error_of(tri + "f 3\n").find("face 2: 1 index, a face needs at least 3"),
              std::string::npos);
}

}  // namespace
}  // namespace kdt
