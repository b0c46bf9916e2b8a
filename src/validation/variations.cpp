#include "emcalign/validation/variations.hpp"

#include <algorithm>

#include "emcalign/core/random.hpp"

namespace emcalign::validation {

namespace {

using sim::SimulationOptions;

// The streams of Rng(sample seed, ·) the patterns draw from: beyond any event's (an event
// number is below sim::kMaxEvents).
constexpr std::uint64_t kGainSeedStream = (1ULL << 62) + 1;
constexpr std::uint64_t kDeadCounterStream = (1ULL << 62) + 2;

// "dead-double": as many more dead counters as the default list has, drawn uniformly among
// the live counters of the whole calorimeter in every sample (dead channels come and go from
// run to run, anywhere).
void moreDeadCounters(SimulationOptions& o, std::uint64_t seed, int counters) {
  Rng rng(seed, kDeadCounterStream);
  const std::size_t more = o.emc.deadCounters.size();
  std::vector<int> dead = o.emc.deadCounters;
  while (dead.size() < 2 * more && static_cast<int>(dead.size()) < counters) {
    const int c = std::min(counters - 1, static_cast<int>(rng.uniform() * counters));
    if (std::find(dead.begin(), dead.end(), c) == dead.end()) dead.push_back(c);
  }
  o.emc.deadCounters = std::move(dead);
}

// "gains-*": each sample draws its own pattern of gains. The counters' gains come from
// Rng(gainSeed, counter); the seed is drawn here, so that they share no stream with the
// sample's events (Rng(seed, event)).
void gainPattern(SimulationOptions& o, std::uint64_t seed, int /*counters*/) {
  o.emc.gainSeed = Rng(seed, kGainSeedStream).next();
}

std::vector<Variation> makeVariations() {
  const std::string tmaxWhy =
      "PDG's t_max = ln(E/Ec) + C is a fit to simulations good to about half a radiation length; 0.5 X0 of NaI "
      "is 1.3 cm, a third of the depth offset the corrections apply";
  const std::string fluctuationWhy =
      "GFLASH's σ(ln t_max) is measured for other calorimeters; half or 1.5 times it brackets NaI";
  const std::string coreWhy =
      "the core/tail split of the lateral profile is assumed (GFLASH fits give 0.65-0.85 in the core)";
  const std::string tailWhy = "the tail radius is assumed; 0.6-1.0 R_M keeps 80-95 % inside 1 R_M";
  const std::string gainWhy =
      "after a calibration with cosmic muons and Bhabha events the counters' gains agree to about 2 %; 5 % is a "
      "poorly calibrated period";
  const std::string layer3Why = "the independent offset of layer 3 is assumed; none and twice it bracket it";
  const std::string deadWhy =
      "dead channels change from run to run: none, or as many more as the default list, anywhere (drawn anew in "
      "every sample)";
  const std::string backgroundWhy =
      "the beam background rate depends on the beams; none, or three times the assumed 0.3 hits per event";
  const std::string tsWhy = "the tracker's resolution in data is known to about 20 %";
  const std::string xpreWhy =
      "the material before the EMC (0.13 X0, the paper) is known to about 0.05 X0; the fit keeps 0.13";
  return {
      {"tmax-up", "t_max", "t_max + 0.5 X0", tmaxWhy, [](SimulationOptions& o) { o.emc.tMaxShift = 0.5; }},
      {"tmax-down", "t_max", "t_max - 0.5 X0", tmaxWhy, [](SimulationOptions& o) { o.emc.tMaxShift = -0.5; }},
      {"fluctuation-up", "t_max fluctuation", "σ(ln t_max) × 1.5", fluctuationWhy,
       [](SimulationOptions& o) { o.emc.tMaxFluctuationScale = 1.5; }},
      {"fluctuation-down", "t_max fluctuation", "σ(ln t_max) × 0.5", fluctuationWhy,
       [](SimulationOptions& o) { o.emc.tMaxFluctuationScale = 0.5; }},
      {"core-up", "lateral core share", "core share 0.85 (0.75)", coreWhy,
       [](SimulationOptions& o) { o.emc.coreFraction = 0.85; }},
      {"core-down", "lateral core share", "core share 0.65 (0.75)", coreWhy,
       [](SimulationOptions& o) { o.emc.coreFraction = 0.65; }},
      {"tail-narrow", "lateral tail radius", "tail radius 0.6 R_M (0.8)", tailWhy,
       [](SimulationOptions& o) { o.emc.tailRadius = 0.6; }},
      {"tail-wide", "lateral tail radius", "tail radius 1.0 R_M (0.8)", tailWhy,
       [](SimulationOptions& o) { o.emc.tailRadius = 1.0; }},
      {"gains-2pc", "counter gains", "gain spread 2 % (none), a pattern per sample", gainWhy,
       [](SimulationOptions& o) { o.emc.counterGainSpread = 0.02; }, gainPattern},
      {"gains-5pc", "counter gains", "gain spread 5 % (none), a pattern per sample", gainWhy,
       [](SimulationOptions& o) { o.emc.counterGainSpread = 0.05; }, gainPattern},
      {"layer3-none", "layer-3 offset", "no layer-3 offset", layer3Why,
       [](SimulationOptions& o) { o.emc.layer3OffsetOn = false; }},
      {"layer3-double", "layer-3 offset", "layer-3 offset × 2", layer3Why,
       [](SimulationOptions& o) { o.emc.layer3Offset *= 2.0; }},
      {"dead-none", "dead counters", "no dead counter (7)", deadWhy,
       [](SimulationOptions& o) { o.emc.deadCountersOn = false; }},
      {"dead-double", "dead counters", "7 more dead counters (7), anywhere, a pattern per sample", deadWhy,
       [](SimulationOptions&) {}, moreDeadCounters},
      {"background-none", "beam background", "no background hits (0.3 per event)", backgroundWhy,
       [](SimulationOptions& o) { o.emc.beamBackground = false; }},
      {"background-triple", "beam background", "0.9 background hits per event (0.3)", backgroundWhy,
       [](SimulationOptions& o) { o.emc.backgroundHitsPerEvent = 0.9; }},
      {"ts-worse", "TS resolution", "TS hit resolution × 1.2", tsWhy,
       [](SimulationOptions& o) {
         o.tracking.sigmaRPhi *= 1.2;
         o.tracking.sigmaZ *= 1.2;
       }},
      {"ts-better", "TS resolution", "TS hit resolution × 0.8", tsWhy,
       [](SimulationOptions& o) {
         o.tracking.sigmaRPhi *= 0.8;
         o.tracking.sigmaZ *= 0.8;
       }},
      {"xpre-up", "material before the EMC", "x_pre 0.18 X0 in the simulation (0.13)", xpreWhy,
       [](SimulationOptions& o) { o.emc.preshowerMaterial = 0.18; }},
      {"xpre-down", "material before the EMC", "x_pre 0.08 X0 in the simulation (0.13)", xpreWhy,
       [](SimulationOptions& o) { o.emc.preshowerMaterial = 0.08; }},
  };
}

}  // namespace

const std::vector<Variation>& variations() {
  static const std::vector<Variation> all = makeVariations();
  return all;
}

std::vector<std::string> variationNames() {
  std::vector<std::string> names;
  names.reserve(variations().size());
  for (const auto& v : variations()) names.push_back(v.name);
  return names;
}

const Variation* findVariation(std::string_view name) {
  for (const auto& v : variations()) {
    if (v.name == name) return &v;
  }
  return nullptr;
}

}  // namespace emcalign::validation
