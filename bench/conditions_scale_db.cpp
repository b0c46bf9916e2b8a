// The database of bench/conditions_scale.py: two tags of N IOVs each (10 runs per IOV, tag b
// shifted by 5 runs so that every IOV of one overlaps two of the other), every IOV its own
// payload, each tag written in one transaction (its history then holds N + 1 changes: its creation and
// every IOV).
//
//   emcalign_bench_conditions_db URI N

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/detector.hpp"

int main(int argc, char** argv) {
  using namespace emcalign;
  if (argc != 3) {
    std::fprintf(stderr, "usage: emcalign_bench_conditions_db URI N\n");
    return 2;
  }
  const std::string uri = argv[1];
  const long n = std::strtol(argv[2], nullptr, 10);
  auto db = conddb::Database::open(uri, conddb::IfMissing::Create);
  if (!db) {
    std::fprintf(stderr, "%s\n", db.error().message.c_str());
    return 1;
  }
  const double r1 = geometry::DetectorDescription::sndDefault().r1();
  for (const auto& [tag, shift] : {std::pair{std::string("a"), 0L}, std::pair{std::string("b"), 5L}}) {
    std::vector<conddb::Database::NewIov> iovs;
    iovs.reserve(static_cast<std::size_t>(n));
    for (long k = 0; k < n; ++k) {
      geometry::AlignmentParameters eta{};
      eta[Param::Alpha] = (2.8 + 1e-5 * static_cast<double>(k) + (shift != 0 ? 0.01 : 0.0)) * units::deg;
      eta[Param::Dx] = 0.3;
      auto p = conddb::makePayload(io::alignmentToJson(eta), r1, "bench", io::Json{{"iov", k}});
      if (!p) {
        std::fprintf(stderr, "%s\n", p.error().message.c_str());
        return 1;
      }
      iovs.push_back({1 + shift + 10 * k, 10 + shift + 10 * k, std::move(*p)});
    }
    // put: the tag created and every IOV a change of its history.
    if (Status s = (*db)->put(tag, iovs, conddb::IfMissing::Create, fmt::format("{} IOVs", n)); !s) {
      std::fprintf(stderr, "tag %s: %s\n", tag.c_str(), s.error().message.c_str());
      return 1;
    }
  }
  std::printf("%s: tags a and b of %ld IOVs each\n", (*db)->uri().c_str(), n);
  return 0;
}
