// Tests of kdt::printable (renderer/core/error.h): every byte value alone, seeded random
// byte strings, and the UTF-8 forms that must be kept or escaped; and Error's location
// fields shown through it; excerpt() and printable_line() for long values and lines.
#include <cstdint>
#include <string>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

// True when s holds no control byte and only well-formed UTF-8 beyond ASCII, decoded here
// independently of printable().
bool safe_to_print(const std::string& s) {
    for (size_t i = 0; i < s.size();) {
        const unsigned char c = static_cast<unsigned char>(s[i]);
        if (c < 0x20 || c == 0x7f) return false;
        if (c < 0x80) {
            ++i;
            continue;
        }
        const size_t n = c >= 0xf0 ? 4 : c >= 0xe0 ? 3 : c >= 0xc0 ? 2 : 0;
        if (n == 0 || i + n > s.size()) return false;
        uint32_t cp = c & (0x7fu >> n);
        for (size_t k = 1; k < n; ++k) {
            const unsigned char t = static_cast<unsigned char>(s[i + k]);
            if ((t & 0xc0) != 0x80) return false;
            cp = (cp << 6) | (t & 0x3fu);
        }
        const uint32_t min = n == 2 ? 0x80 : n == 3 ? 0x800 : 0x10000;
        if (cp < min || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return false;
        if (cp <= 0x9f || cp == 0x202e || cp == 0x200b) return false;  // C1, RLO, ZWSP
        i += n;
    }
    return true;
}

TEST(Printable, EveryByteAlone) {
    for (int b = 0; b < 256; ++b) {
        const std::string in(1, char(b));
        const std::string out = printable(in);
        EXPECT_TRUE(safe_to_print(out)) << b;
        if (b >= 0x20 && b < 0x7f) {
            EXPECT_EQ(out, in);
        } else if (b != '\t' && b != '\n' && b != '\r') {
            char want[8];
            std::snprintf(want, sizeof(want), "\\x%02x", b);
            EXPECT_EQ(out, want);
        }
    }
    EXPECT_EQ(printable("\t\n\r\\"), "\\t\\n\\r\\");
}

TEST(Printable, NulEscBelDoNotCutOrDriveTheMessage) {
    const std::string in(
        "a\0b\x1b[31mc\x07"
        "d",
        11);
    EXPECT_EQ(printable(in), "a\\x00b\\x1b[31mc\\x07d");
}

TEST(Printable, Utf8KeptWhenWellFormedAndVisible) {
    EXPECT_EQ(printable("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80"),
              "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80");
    // Overlong, surrogate, above U+10FFFF, cut short, stray continuation bytes.
    EXPECT_EQ(printable("\xc0\xaf"), "\\xc0\\xaf");
    EXPECT_EQ(printable("\xe0\x80\xaf"), "\\xe0\\x80\\xaf");
    EXPECT_EQ(printable("\xed\xa0\x80"), "\\xed\\xa0\\x80");
    EXPECT_EQ(printable("\xf4\x90\x80\x80"), "\\xf4\\x90\\x80\\x80");
    EXPECT_EQ(printable("x\xe2\x82"), "x\\xe2\\x82");
    EXPECT_EQ(printable("\x80\xbf"), "\\x80\\xbf");
    // C1 CSI, soft hyphen, zero-width space, right-to-left override, byte order mark.
    EXPECT_EQ(printable("\xc2\x9b"
                        "31m"),
              "\\u009b31m");
    EXPECT_EQ(printable("\xc2\xad"), "\\u00ad");
    EXPECT_EQ(printable("\xe2\x80\x8b"), "\\u200b");
    EXPECT_EQ(printable("a\xe2\x80\xae"
                        "b"),
              "a\\u202eb");
    EXPECT_EQ(printable("\xef\xbb\xbf"), "\\ufeff");
}

TEST(Printable, RandomBytesAlwaysComeOutSafe) {
    test::HashRng rng(29);
    for (int n = 0; n < 2000; ++n) {
        std::string in(size_t(rng.next_u64() % 24), '\0');
        for (char& c : in) {
            // Mostly high bytes and controls, where the cases are.
            const uint64_t r = rng.next_u64();
            c = char(r % 3 == 0 ? 0x80 + (r >> 8) % 0x80 : r % 3 == 1 ? (r >> 8) % 0x20 : r >> 8);
        }
        const std::string out = printable(in);
        EXPECT_TRUE(safe_to_print(out)) << out;
        // Nothing is dropped: every input byte leaves at least one byte of output.
        EXPECT_GE(out.size(), in.size());
    }
}

TEST(Printable, ErrorLocationFieldsAreShownThroughIt) {
    ErrorLocation w;
    w.path = std::string("m\x1b]0;x\x07.ply", 11);
    w.element = std::string("fa\0ce", 5);
    w.index = 3;
    const Error e(w, "bad");
    EXPECT_EQ(std::string(e.what()), "m\\x1b]0;x\\x07.ply: fa\\x00ce 3: bad");
    EXPECT_EQ(e.where().path, w.path);  // the location itself is kept as given
}

TEST(Excerpt, ShortTextIsPrintableUnchanged) {
    EXPECT_EQ(excerpt("ab\x01c"), printable("ab\x01c"));
    EXPECT_EQ(excerpt(std::string(120, 'x')), std::string(120, 'x'));
}

TEST(Excerpt, LongTextKeepsItsHeadAndSize) {
    EXPECT_EQ(excerpt(std::string(100000, 'k')), std::string(120, 'k') + "... [100000 bytes]");
    // A cut never splits a UTF-8 sequence: "\xc3\xa9" straddles byte 120 here.
    const std::string e = std::string(119, 'a') + "\xc3\xa9" + std::string(50, 'b');
    const std::string out = excerpt(e);
    EXPECT_EQ(out, std::string(119, 'a') + "... [171 bytes]");
    EXPECT_TRUE(safe_to_print(out)) << out;
}

TEST(Excerpt, WholeLinesKeepHeadAndTail) {
    const std::string m = "f.json: " + std::string(50000, 'v') + ": unknown key";
    const std::string out = printable_line(m, 4096);
    EXPECT_LT(out.size(), 4200u);
    EXPECT_EQ(out.rfind("f.json: ", 0), 0u);
    EXPECT_EQ(out.substr(out.size() - 13), ": unknown key");
    EXPECT_NE(out.find(" bytes left out] ... "), std::string::npos);
    EXPECT_EQ(printable_line("short \x07"), printable("short \x07"));
}

TEST(Excerpt, ErrorElementsAreShortened) {
    const Error e(ErrorLocation{"s.json", "meshes/0/" + std::string(100000, 'k')}, "unknown key");
    EXPECT_LT(std::string(e.what()).size(), 400u);
    EXPECT_NE(std::string(e.what()).find("[100009 bytes]: unknown key"), std::string::npos);
}

}  // namespace
}  // namespace kdt
