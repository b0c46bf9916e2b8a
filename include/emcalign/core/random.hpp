#pragma once
// Seeded random numbers that give the same sequence on every machine and thread count.
//
// `Rng` is xoshiro256** (Blackman & Vigna), seeded through SplitMix64 from a (seed, stream)
// pair: the simulation gives event i the stream i, so an event's numbers do not depend on
// which thread made it or on what was generated before. The distributions are written
// here, not taken from <random>, whose algorithms differ between standard libraries.

#include <cmath>
#include <cstdint>
#include <numbers>

namespace emcalign {

class Rng {
 public:
  Rng(std::uint64_t seed, std::uint64_t stream) {
    std::uint64_t x = seed ^ (0x9E3779B97F4A7C15ULL * (stream + 1));
    for (auto& s : state_) s = splitmix64(x);
  }

  std::uint64_t next() {
    const std::uint64_t result = rotl(state_[1] * 5, 7) * 9;
    const std::uint64_t t = state_[1] << 17;
    state_[2] ^= state_[0];
    state_[3] ^= state_[1];
    state_[1] ^= state_[2];
    state_[0] ^= state_[3];
    state_[2] ^= t;
    state_[3] = rotl(state_[3], 45);
    return result;
  }

  /// Uniform in [0, 1), 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  /// Uniform in (0, 1]: safe under log().
  double uniformOpen() { return 1.0 - uniform(); }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }

  /// Standard normal (Marsaglia polar method; the second value is kept for the next call).
  double normal() {
    if (hasSpare_) {
      hasSpare_ = false;
      return spare_;
    }
    double u, v, s;
    do {
      u = 2.0 * uniform() - 1.0;
      v = 2.0 * uniform() - 1.0;
      s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double f = std::sqrt(-2.0 * std::log(s) / s);
    spare_ = v * f;
    hasSpare_ = true;
    return u * f;
  }
  double normal(double mean, double sigma) { return mean + sigma * normal(); }

  double exponential(double mean) { return -mean * std::log(uniformOpen()); }

  /// Poisson by multiplication of uniforms (meant for small means, ≲ 30).
  int poisson(double mean) {
    if (mean <= 0.0) return 0;
    const double limit = std::exp(-mean);
    int k = 0;
    double p = uniform();
    while (p > limit) {
      ++k;
      p *= uniform();
    }
    return k;
  }

  /// Gamma(shape k, scale θ) by Marsaglia & Tsang (with the k < 1 boost).
  double gamma(double shape, double scale) {
    if (shape < 1.0) return gamma(shape + 1.0, scale) * std::pow(uniformOpen(), 1.0 / shape);
    const double d = shape - 1.0 / 3.0, c = 1.0 / std::sqrt(9.0 * d);
    while (true) {
      double x, v;
      do {
        x = normal();
        v = 1.0 + c * x;
      } while (v <= 0.0);
      v = v * v * v;
      const double u = uniformOpen();
      if (u < 1.0 - 0.0331 * x * x * x * x) return d * v * scale;
      if (std::log(u) < 0.5 * x * x + d * (1.0 - v + std::log(v))) return d * v * scale;
    }
  }

  /// A uniformly random unit vector in the plane: (cos φ, sin φ) without trigonometry.
  void unitCircle(double& c, double& s) {
    double u, v, r2;
    do {
      u = 2.0 * uniform() - 1.0;
      v = 2.0 * uniform() - 1.0;
      r2 = u * u + v * v;
    } while (r2 >= 1.0 || r2 == 0.0);
    c = (u * u - v * v) / r2;
    s = 2.0 * u * v / r2;
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  static std::uint64_t splitmix64(std::uint64_t& x) {
    std::uint64_t z = (x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }

  std::uint64_t state_[4];
  double spare_ = 0.0;
  bool hasSpare_ = false;
};

}  // namespace emcalign
