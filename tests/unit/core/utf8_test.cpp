#include "emcalign/core/utf8.hpp"

#include <gtest/gtest.h>

#include <string>

namespace emcalign {
namespace {

TEST(Utf8, AcceptsValidText) {
  EXPECT_TRUE(isValidUtf8(""));
  EXPECT_TRUE(isValidUtf8("run_0001.h5"));
  EXPECT_TRUE(isValidUtf8("σ_sys ± 0.2° → γγ"));      // 2- and 3-byte sequences
  EXPECT_TRUE(isValidUtf8("\xF0\x9F\x93\x88 plot"));  // U+1F4C8, 4 bytes
  EXPECT_TRUE(isValidUtf8("\xF4\x8F\xBF\xBF"));       // U+10FFFF, the last code point
  EXPECT_TRUE(isValidUtf8(std::string("a\0b", 3)));   // NUL is ASCII
}

TEST(Utf8, RefusesWhatIsNot) {
  EXPECT_FALSE(isValidUtf8("fit\xff.h5"));        // never in UTF-8
  EXPECT_FALSE(isValidUtf8("\x89HDF\r\n"));       // a continuation byte alone
  EXPECT_FALSE(isValidUtf8("\xC3"));              // cut short at the end
  EXPECT_FALSE(isValidUtf8("\xE2\x82"));          // cut short
  EXPECT_FALSE(isValidUtf8("\xC3x"));             // not a continuation
  EXPECT_FALSE(isValidUtf8("\xC0\xAF"));          // overlong '/'
  EXPECT_FALSE(isValidUtf8("\xE0\x80\xAF"));      // overlong, 3 bytes
  EXPECT_FALSE(isValidUtf8("\xED\xA0\x80"));      // a surrogate, U+D800
  EXPECT_FALSE(isValidUtf8("\xF4\x90\x80\x80"));  // above U+10FFFF
  EXPECT_FALSE(isValidUtf8("\xF5\x80\x80\x80"));
}

TEST(Utf8, AnArgumentWithAControlCharacterOrNotUtf8IsRefusedByItsPosition) {
  EXPECT_EQ(argumentRefusal("run_1001.h5", 3), "");
  EXPECT_EQ(argumentRefusal("tab\tin a name", 1), "");
  EXPECT_EQ(argumentRefusal("Räume/run.h5", 2), "");
  for (const char* forged : {"a\nb", "a\rb", "a\x1b[2Jb", "a\x7f"}) {
    EXPECT_EQ(argumentRefusal(forged, 4).rfind("argument 4 holds a control character", 0), 0u) << forged;
  }
  EXPECT_EQ(argumentRefusal("r\xe4ume", 5).rfind("argument 5 is not valid UTF-8", 0), 0u);
}

TEST(Utf8, PrintableEscapesWhatATerminalWouldObey) {
  EXPECT_EQ(printable("plain text, ünïcode, ψ"), "plain text, ünïcode, ψ");
  EXPECT_EQ(printable("\x1b]0;owned\a\x1b[2J"), "\\x1b]0;owned\\x07\\x1b[2J");
  EXPECT_EQ(printable("a\tb\nc\rd\x7f"), "a\\x09b\\x0ac\\x0dd\\x7f");
  EXPECT_EQ(printable("naiv\xe9"), "naiv\\xe9");  // not UTF-8: the byte, escaped
  EXPECT_EQ(printable("\xC2\x9B"
                      "2J"),
            "\\u009b2J");  // C1 CSI
  EXPECT_EQ(printable(std::string_view("a\0b", 3)), "a\\x00b");
  // Whatever goes in, what comes out is valid UTF-8 without control characters.
  std::string all;
  for (int c = 0; c < 256; ++c) all += static_cast<char>(c);
  const std::string out = printable(all);
  EXPECT_TRUE(isValidUtf8(out));
  for (unsigned char c : out) EXPECT_FALSE(c < 0x20 || c == 0x7f) << static_cast<int>(c);
}

}  // namespace
}  // namespace emcalign
