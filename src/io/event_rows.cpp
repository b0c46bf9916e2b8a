#include <algorithm>
#include <cmath>
#include <set>

#include <fmt/format.h>

#include "emcalign/core/beam_energy.hpp"
#include "event_file_internal.hpp"

namespace emcalign::io::detail {

std::optional<Issue> checkRow(const ParticleRow& r) {
  const auto name = [](int c) { return kColumnNames[static_cast<std::size_t>(c)]; };
  const std::array<double, kNumCols> v = {0.0,   0.0,     r.beamEnergy, 0.0,      0.0,      r.z0,
                                          r.rho, r.phiTs, r.thetaTs,    r.energy, r.phiEmc, r.thetaEmc};
  for (int c = kBeam; c < kNumCols; ++c) {
    if (std::isinf(v[static_cast<std::size_t>(c)])) {
      return Issue{name(c), fmt::format("{} is not a finite number", v[static_cast<std::size_t>(c)])};
    }
  }
  if (std::isnan(r.beamEnergy)) return Issue{name(kBeam), "empty (a value is required)"};
  if (std::string problem = beamEnergyProblem(r.beamEnergy * units::MeV); !problem.empty()) {
    return Issue{name(kBeam), std::move(problem)};
  }
  if (r.muonVeto != 0 && r.muonVeto != 1) {
    return Issue{name(kVeto), fmt::format("must be 0 or 1, got {}", static_cast<int>(r.muonVeto))};
  }
  if (r.charged != 0 && r.charged != 1) {
    return Issue{name(kCharged), fmt::format("must be 0 or 1, got {}", static_cast<int>(r.charged))};
  }
  for (int c = kZ0; c <= kThetaTs; ++c) {
    const double x = v[static_cast<std::size_t>(c)];
    if (r.charged == 1 && std::isnan(x)) {
      return Issue{name(c),
                   "empty, but a charged particle (charged = 1) needs a complete track "
                   "(z0_cm, rho_cm, phi_ts_rad, theta_ts_rad)"};
    }
    if (r.charged == 0 && !std::isnan(x)) {
      return Issue{name(c), fmt::format("must be empty for a photon (charged = 0), got {}", x)};
    }
  }
  if (!std::isnan(r.phiTs) && (r.phiTs < 0.0 || r.phiTs > kTwoPi)) {
    return Issue{name(kPhiTs), fmt::format("{} is outside [0, 2*pi]", r.phiTs)};
  }
  if (!std::isnan(r.thetaTs) && (r.thetaTs < 0.0 || r.thetaTs > kPi)) {
    return Issue{name(kThetaTs), fmt::format("{} is outside [0, pi]", r.thetaTs)};
  }
  int clusterFields = 0;
  for (int c = kEnergy; c <= kThetaEmc; ++c) clusterFields += std::isnan(v[static_cast<std::size_t>(c)]) ? 0 : 1;
  if (clusterFields == 0 && r.charged == 0) {
    return Issue{name(kEnergy), "empty, but a photon (charged = 0) needs an EMC cluster"};
  }
  if (clusterFields != 0 && clusterFields != 3) {
    for (int c = kEnergy; c <= kThetaEmc; ++c) {
      if (std::isnan(v[static_cast<std::size_t>(c)])) {
        return Issue{name(c),
                     "empty while other cluster fields are filled (energy_mev, phi_emc_rad and "
                     "theta_emc_rad are all filled or all empty)"};
      }
    }
  }
  if (!std::isnan(r.energy) && r.energy < 0.0) {
    return Issue{name(kEnergy), fmt::format("negative energy {}", r.energy)};
  }
  if (!std::isnan(r.phiEmc) && (r.phiEmc < 0.0 || r.phiEmc > kTwoPi)) {
    return Issue{name(kPhiEmc), fmt::format("{} is outside [0, 2*pi]", r.phiEmc)};
  }
  if (!std::isnan(r.thetaEmc) && (r.thetaEmc < 0.0 || r.thetaEmc > kPi)) {
    return Issue{name(kThetaEmc), fmt::format("{} is outside [0, pi]", r.thetaEmc)};
  }
  return std::nullopt;
}

std::optional<Issue> checkHits(const ParticleRow& r, std::span<const Hit> hits) {
  if (r.hitCount < 0 || r.hitCount > kMaxHitsPerRow) {
    return Issue{"hit_count", fmt::format("{} is outside [0, {}]", r.hitCount, kMaxHitsPerRow)};
  }
  if (std::isnan(r.energy) && r.hitCount != 0) {
    return Issue{"hit_count", fmt::format("{} hits for a row without an EMC cluster", r.hitCount)};
  }
  if (!std::isnan(r.energy) && r.hitCount == 0) {
    return Issue{"hit_count",
                 "0 hits for a row with an EMC cluster (a file with hits stores every cluster's counters)"};
  }
  for (const Hit& h : hits) {
    if (h.counter < 0) return Issue{"/hits/counter", fmt::format("{} is not a counter index", h.counter)};
    if (!(std::isfinite(h.energy) && h.energy >= 0.0)) {
      return Issue{"/hits/energy_mev", fmt::format("{} is not a finite energy >= 0", h.energy)};
    }
  }
  return std::nullopt;
}

bool isAttributeKey(std::string_view key) {
  if (key.empty()) return false;
  for (char ch : key) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '_' ||
                    ch == '.' || ch == '-';
    if (!ok) return false;
  }
  return true;
}

Status checkAttributes(const std::string& path, const Attributes& attributes, EventFormat format) {
  for (std::size_t i = 0; i < attributes.size(); ++i) {
    const auto& [key, value] = attributes[i];
    if (!isAttributeKey(key)) {
      return Error{fmt::format("{}: attribute '{}': a key is made of letters, digits, '_', '.' and '-'", path, key)};
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (attributes[j].first == key) {
        return Error{fmt::format("{}: attribute '{}': given twice", path, key)};
      }
    }
    if (value.find('\0') != std::string::npos) {
      return Error{fmt::format("{}: attribute '{}': the value contains a NUL character", path, key)};
    }
    if (format == EventFormat::Csv && value.find_first_of("\r\n") != std::string::npos) {
      return Error{
          fmt::format("{}: attribute '{}': the value contains a line break, which a CSV comment line cannot "
                      "hold (write it on one line, e.g. compact JSON)",
                      path, key)};
    }
  }
  return {};
}

Status checkAppend(const std::string& path, std::span<const ParticleRow> rows, std::span<const Hit> hits, bool withHits,
                   std::uint64_t firstIndex, EventConsistency& consistency) {
  EventConsistency trial = consistency;
  std::size_t hit = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    auto issue = checkRow(rows[i]);
    if (!issue) issue = trial.check(rows[i]);
    if (!issue && withHits) {
      const auto n = static_cast<std::size_t>(std::max(0, rows[i].hitCount));
      if (hit + n > hits.size()) {
        return Error{fmt::format("{}: append: the rows have more hits than the {} given", path, hits.size())};
      }
      issue = checkHits(rows[i], hits.subspan(hit, n));
      hit += n;
    }
    if (issue) {
      return Error{fmt::format("{}: appended row {} (0-based, run {} event {}): column '{}': {}", path, firstIndex + i,
                               rows[i].run, rows[i].event, issue->column, issue->what)};
    }
  }
  if (withHits && hit != hits.size()) {
    return Error{fmt::format("{}: append: {} hits given for rows that have {}", path, hits.size(), hit)};
  }
  consistency = trial;
  return {};
}

}  // namespace emcalign::io::detail

namespace emcalign::io {

Status checkRowsInMemory(std::span<const ParticleRow> rows, const std::string& source) {
  detail::EventConsistency consistency;
  std::set<std::pair<std::int32_t, std::int64_t>> seen;
  int eventRows = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const ParticleRow& r = rows[i];
    const auto where = [&] { return fmt::format("{}: row {} (run {}, event {})", source, i, r.run, r.event); };
    auto issue = detail::checkRow(r);
    if (!issue) issue = consistency.check(r);
    if (issue) return Error{fmt::format("{}: column '{}': {}", where(), issue->column, issue->what)};
    if (i > 0 && sameEvent(r, rows[i - 1])) {
      if (++eventRows > detail::kMaxRowsPerEvent) {
        return Error{
            fmt::format("{}: the event has more than {} rows: an event holds a handful of particles (are "
                        "the run and event columns filled?)",
                        where(), detail::kMaxRowsPerEvent)};
      }
      continue;
    }
    eventRows = 1;
    if (!seen.insert({r.run, r.event}).second) {
      return Error{
          fmt::format("{}: the event appears again: each event must appear once, its rows together (are "
                      "two samples concatenated, or the rows not in event order?)",
                      where())};
    }
  }
  return {};
}

}  // namespace emcalign::io
