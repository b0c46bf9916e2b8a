#pragma once
// Reading an event file whole in tests.

#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "emcalign/io/event_file.hpp"

namespace emcalign::testing {

/// Every row of `file` (a failure is reported to GoogleTest and gives none).
inline std::vector<ParticleRow> rowsOf(const std::string& file) {
  auto reader = io::EventReader::open({file});
  EXPECT_TRUE(reader.ok()) << (reader.ok() ? "" : reader.error().message);
  std::vector<ParticleRow> all, block;
  if (!reader.ok()) return all;
  while (*(*reader)->next(block)) all.insert(all.end(), block.begin(), block.end());
  return all;
}

}  // namespace emcalign::testing
