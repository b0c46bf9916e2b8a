#include "emcalign/core/sha256.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace emcalign {
namespace {

// The test vectors of FIPS 180-4's examples (NIST CSRC "SHA256.pdf").
TEST(Sha256, NistVectors) {
  EXPECT_EQ(sha256(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(sha256(std::string(1000000, 'a')), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

// Fed in pieces of every size, the digest is the same as in one piece (the block boundary
// and the padding at 55/56/64 bytes are where implementations go wrong).
TEST(Sha256, PiecesGiveTheSameDigest) {
  std::string text;
  for (int i = 0; i < 300; ++i) text.push_back(static_cast<char>('a' + i % 26));
  for (std::size_t n : {0U, 1U, 55U, 56U, 63U, 64U, 65U, 119U, 120U, 128U, 300U}) {
    const std::string whole = sha256(text.substr(0, n));
    for (std::size_t piece : {1U, 3U, 63U, 64U}) {
      Sha256 h;
      for (std::size_t i = 0; i < n; i += piece) h.update(std::string_view(text).substr(i, std::min(piece, n - i)));
      EXPECT_EQ(h.hex(), whole) << "length " << n << ", pieces of " << piece;
    }
  }
  EXPECT_NE(sha256(text.substr(0, 55)), sha256(text.substr(0, 56)));
}

}  // namespace
}  // namespace emcalign

namespace emcalign {
namespace {

TEST(Sha256, OfFileIsOfItsBytes) {
  const std::string path = ::testing::TempDir() + "emcalign-sha256-file";
  std::string text;
  for (int i = 0; i < 3 * (1 << 20) + 17; ++i) text.push_back(static_cast<char>(i * 7 % 251));
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    std::fwrite(text.data(), 1, text.size(), f);
    std::fclose(f);
  }
  auto digest = sha256OfFile(path);
  ASSERT_TRUE(digest) << digest.error().message;
  EXPECT_EQ(*digest, sha256(text));
  std::remove(path.c_str());
  auto missing = sha256OfFile(path);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find(path), std::string::npos);
}

}  // namespace
}  // namespace emcalign
