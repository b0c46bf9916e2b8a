#pragma once
// SHA-256 (FIPS 180-4, by OpenSSL's libcrypto): the content address of a conditions payload,
// and the digest of the files a calibration was made from.

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "emcalign/core/result.hpp"

namespace emcalign {

class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(Sha256&&) noexcept;
  Sha256& operator=(Sha256&&) noexcept;
  void update(const void* data, std::size_t size);
  void update(std::string_view text) { update(text.data(), text.size()); }
  /// The digest as 64 lowercase hex digits; the object is then spent.
  std::string hex();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// The digest of a text.
std::string sha256(std::string_view text);

/// The digest of a file's bytes; the error names the file.
Result<std::string> sha256OfFile(const std::string& path);

}  // namespace emcalign
