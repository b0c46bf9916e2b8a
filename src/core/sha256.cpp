#include "emcalign/core/sha256.hpp"

#include <openssl/evp.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>

#include "emcalign/core/regular_file.hpp"

namespace emcalign {

struct Sha256::State {
  EVP_MD_CTX* ctx = nullptr;
  ~State() { EVP_MD_CTX_free(ctx); }
};

Sha256::Sha256() : state_(std::make_unique<State>()) {
  state_->ctx = EVP_MD_CTX_new();
  if (state_->ctx == nullptr || EVP_DigestInit_ex(state_->ctx, EVP_sha256(), nullptr) != 1) {
    throw std::runtime_error("OpenSSL: cannot start a SHA-256 digest");
  }
}
Sha256::~Sha256() = default;
Sha256::Sha256(Sha256&&) noexcept = default;
Sha256& Sha256::operator=(Sha256&&) noexcept = default;

void Sha256::update(const void* data, std::size_t size) {
  if (size > 0 && EVP_DigestUpdate(state_->ctx, data, size) != 1) {
    throw std::runtime_error("OpenSSL: SHA-256 update failed");
  }
}

std::string Sha256::hex() {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  if (EVP_DigestFinal_ex(state_->ctx, digest, &size) != 1) throw std::runtime_error("OpenSSL: SHA-256 final failed");
  std::string out;
  out.reserve(2 * size);
  for (unsigned int i = 0; i < size; ++i) out += fmt::format("{:02x}", digest[i]);
  return out;
}

std::string sha256(std::string_view text) {
  Sha256 h;
  h.update(text);
  return h.hex();
}

Result<std::string> sha256OfFile(const std::string& path) {
  auto file = RegularFile::open(path);
  if (!file) return file.error();
  Sha256 h;
  std::vector<char> buffer(1 << 20);
  while (true) {
    auto n = file->read(buffer.data(), buffer.size());
    if (!n) return n.error();
    h.update(buffer.data(), *n);
    if (*n < buffer.size()) break;
  }
  return h.hex();
}

}  // namespace emcalign
