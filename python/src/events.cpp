// Event files as numpy columns, and docs/contract.md §7's selection on them.

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <set>
#include <span>

#include "bindings.hpp"
#include "emcalign/calib/selection.hpp"
#include "emcalign/core/beam_energy.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/event_file.hpp"

namespace emcalign::python {

namespace {

// An event file's rows as numpy columns (docs/contract.md §6 names and units), with its truth and hits
// when it has them and they are asked for.
py::dict readEvents(const Paths& paths, bool truth, bool hits) {
  io::ReaderOptions o;
  o.truth = truth;
  o.hits = hits;
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truthRows;
  std::vector<Hit> hitRows;
  bool withTruth = truth, withHits = hits;
  const std::vector<std::string> files = stringsOf(paths);  // may raise: with the GIL
  Status status;
  {
    py::gil_scoped_release release;
    auto reader = io::EventReader::open(files, o);
    if (!reader) status = reader.error();
    std::vector<ParticleRow> block;
    while (status) {
      auto more = (*reader)->next(block);
      if (!more) status = more.error();
      if (!status || !*more) break;
      rows.insert(rows.end(), block.begin(), block.end());
      const auto* t = (*reader)->truth();
      const auto* h = (*reader)->hits();
      withTruth = withTruth && t != nullptr;
      withHits = withHits && h != nullptr;
      if (withTruth) truthRows.insert(truthRows.end(), t->begin(), t->end());
      if (withHits) hitRows.insert(hitRows.end(), h->begin(), h->end());
    }
  }
  check(status);
  return eventColumns(rows, withTruth ? &truthRows : nullptr, withHits ? &hitRows : nullptr);
}

// A column of the dict read_events gives (or any dict of the same columns), checked.
py::array columnArray(const py::dict& events, const char* key, std::size_t n) {
  if (!events.contains(key)) raise(Error{fmt::format("events: no column '{}' (a dict as read_events gives)", key)});
  auto a = py::array::ensure(events[key]);
  if (!a || a.ndim() != 1 || static_cast<std::size_t>(a.shape(0)) != n) {
    raise(Error{fmt::format("events: column '{}' is not a 1-D array of {} rows", key, n)});
  }
  const char kind = a.dtype().kind();
  if (kind != 'i' && kind != 'u' && kind != 'f' && kind != 'b') {
    raise(Error{
        fmt::format("events: column '{}' is not numeric (dtype {})", key, py::str(a.dtype()).cast<std::string>())});
  }
  return a;
}

// The rows a numpy masked array masks (what awkward and uproot give for optional fields); none
// for a plain array. A masked entry is a missing value, never the data under its mask.
std::vector<std::size_t> maskedRows(const py::dict& events, const char* key, std::size_t n) {
  const py::object column = events[key];
  if (!py::hasattr(column, "mask")) return {};
  const auto mask = py::array_t<bool, py::array::c_style | py::array::forcecast>::ensure(
      py::module_::import("numpy.ma").attr("getmaskarray")(column));
  std::vector<std::size_t> out;
  if (!mask || static_cast<std::size_t>(mask.size()) != n) return out;
  for (std::size_t i = 0; i < n; ++i) {
    if (mask.data()[i]) out.push_back(i);
  }
  return out;
}

// A float column; masked entries are missing (NaN), as an empty CSV field is.
std::vector<double> columnOf(const py::dict& events, const char* key, std::size_t n) {
  const auto a = Array::ensure(columnArray(events, key, n));
  std::vector<double> out(a.data(), a.data() + n);
  for (std::size_t i : maskedRows(events, key, n)) out[i] = std::numeric_limits<double>::quiet_NaN();
  return out;
}

// An integer column, exactly (an event number above 2^53 is not a double): integers as they
// are, floats only where every value is a whole number in [lo, hi].
std::vector<std::int64_t> integerColumnOf(const py::dict& events, const char* key, std::size_t n, std::int64_t lo,
                                          std::int64_t hi) {
  const py::array a = columnArray(events, key, n);
  if (const auto masked = maskedRows(events, key, n); !masked.empty()) {
    raise(
        Error{fmt::format("events: row {}: {} is masked (missing), and every row needs one: fill it, or leave "
                          "the row out",
                          masked.front(), key)});
  }
  std::vector<std::int64_t> out(n);
  const char kind = a.dtype().kind();
  if (kind == 'f') {
    const auto d = Array::ensure(a);
    for (std::size_t i = 0; i < n; ++i) {
      const double v = d.data()[i];
      if (std::isfinite(v) && std::abs(v) >= 9007199254740992.0) {
        raise(
            Error{fmt::format("events: row {}: {} {} is a float beyond 2^53, where floats hold no exact integer: "
                              "give the column as integers (int64)",
                              i, key, v)});
      }
      if (!(std::isfinite(v) && v == std::floor(v) && v >= static_cast<double>(lo) && v <= static_cast<double>(hi))) {
        raise(Error{fmt::format("events: row {}: {} {} is not an integer in [{}, {}]", i, key, v, lo, hi)});
      }
      out[i] = static_cast<std::int64_t>(v);
    }
    return out;
  }
  if (kind == 'u' && a.itemsize() == 8) {  // above 2^63 would wrap
    const auto u = py::array_t<std::uint64_t, py::array::c_style | py::array::forcecast>::ensure(a);
    for (std::size_t i = 0; i < n; ++i) {
      if (u.data()[i] > static_cast<std::uint64_t>(hi)) {
        raise(Error{fmt::format("events: row {}: {} {} is not an integer in [{}, {}]", i, key, u.data()[i], lo, hi)});
      }
    }
  }
  const auto v = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(a);
  for (std::size_t i = 0; i < n; ++i) {
    if (v.data()[i] < lo || v.data()[i] > hi) {
      raise(Error{fmt::format("events: row {}: {} {} is not an integer in [{}, {}]", i, key, v.data()[i], lo, hi)});
    }
    out[i] = v.data()[i];
  }
  return out;
}

}  // namespace

std::vector<ParticleRow> rowsOf(const py::dict& events) {
  if (!events.contains("run")) raise(Error{"events: no column 'run' (a dict as read_events gives)"});
  const auto n = static_cast<std::size_t>(py::len(events["run"]));
  using Limits32 = std::numeric_limits<std::int32_t>;
  const auto run = integerColumnOf(events, "run", n, Limits32::min(), Limits32::max());
  const auto event = integerColumnOf(events, "event", n, std::numeric_limits<std::int64_t>::min(),
                                     std::numeric_limits<std::int64_t>::max());
  const auto veto = integerColumnOf(events, "muon_veto", n, 0, 1);
  const auto charged = integerColumnOf(events, "charged", n, 0, 1);
  const auto beam = columnOf(events, "beam_energy_mev", n);
  const auto z0 = columnOf(events, "z0_cm", n), rho = columnOf(events, "rho_cm", n);
  const auto phiTs = columnOf(events, "phi_ts_rad", n), thetaTs = columnOf(events, "theta_ts_rad", n);
  const auto energy = columnOf(events, "energy_mev", n);
  const auto phiEmc = columnOf(events, "phi_emc_rad", n), thetaEmc = columnOf(events, "theta_emc_rad", n);
  std::vector<ParticleRow> rows(n);
  for (std::size_t i = 0; i < n; ++i) {
    ParticleRow& r = rows[i];
    r.run = static_cast<std::int32_t>(run[i]);
    r.event = event[i];
    r.beamEnergy = beam[i];
    r.muonVeto = static_cast<std::int8_t>(veto[i]);
    r.charged = static_cast<std::int8_t>(charged[i]);
    r.z0 = z0[i];
    r.rho = rho[i];
    r.phiTs = phiTs[i];
    r.thetaTs = thetaTs[i];
    r.energy = energy[i];
    r.phiEmc = phiEmc[i];
    r.thetaEmc = thetaEmc[i];
  }
  // The rules a file's rows obey (io/event_file.hpp): values, an event's rows together, each
  // event once.
  check(io::checkRowsInMemory(rows, "events"));
  return rows;
}

namespace {

// The selection (docs/fit.md) on the rows of `events`: per row, the index (1..5, CutFlow::kNames) of
// the first cut its event fails, 0 when the event is selected. An event is its consecutive
// rows of one (run, event).
py::array_t<int> selectRows(const py::dict& events, const calib::SelectionOptions& options) {
  const std::vector<ParticleRow> rows = rowsOf(events);
  const std::size_t n = rows.size();
  py::array_t<int> out(static_cast<py::ssize_t>(n));
  auto w = out.mutable_unchecked<1>();
  py::gil_scoped_release release;
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i + 1;
    while (j < n && sameEvent(rows[j], rows[i])) ++j;
    const int cut = calib::selectEvent(std::span<const ParticleRow>(rows.data() + i, j - i), options);
    for (std::size_t k = i; k < j; ++k) w(static_cast<py::ssize_t>(k)) = cut;
    i = j;
  }
  return out;
}

}  // namespace

void bindEvents(py::module_& m) {
  m.def("read_events", &readEvents, py::arg("paths"), py::arg("truth") = true, py::arg("hits") = true,
        "the rows of event files (HDF5 or CSV, docs/simulation.md) as a dict of numpy columns, with 'truth' and 'hits' "
        "dicts when the files have them");

  std::vector<std::string> cuts(calib::CutFlow::kNames.begin(), calib::CutFlow::kNames.end());
  m.attr("CUTS") = cuts;
  m.def(
      "select",
      [](const py::dict& events, std::optional<double> beamEnergy, std::optional<double> maxAbsZ0,
         std::optional<double> maxAbsRho, std::optional<double> minEnergyFraction,
         std::optional<double> maxEnergyFraction, std::optional<double> maxAcollinearityDeg) {
        calib::SelectionOptions o;  // docs/contract.md §7's cuts, unless given
        if (beamEnergy) {
          if (std::string problem = beamEnergyProblem(*beamEnergy * units::MeV); !problem.empty()) {
            raise(Error{"select: beam_energy " + problem});
          }
          o.beamEnergy = *beamEnergy * units::MeV;
        }
        if (maxAbsZ0) o.maxAbsZ0 = *maxAbsZ0 * units::cm;
        if (maxAbsRho) o.maxAbsRho = *maxAbsRho * units::cm;
        if (minEnergyFraction) o.minEnergyFraction = *minEnergyFraction;
        if (maxEnergyFraction) o.maxEnergyFraction = *maxEnergyFraction;
        if (maxAcollinearityDeg) o.maxAcollinearity = *maxAcollinearityDeg * units::deg;
        check(o.validate());
        return selectRows(events, o);
      },
      py::arg("events"), py::kw_only(), py::arg("beam_energy") = py::none(), py::arg("max_abs_z0") = py::none(),
      py::arg("max_abs_rho") = py::none(), py::arg("min_energy_fraction") = py::none(),
      py::arg("max_energy_fraction") = py::none(), py::arg("max_acollinearity_deg") = py::none(),
      "The selection (docs/fit.md) on the rows of read_events: per row, the index in CUTS of the first cut its event "
      "fails, 0 when selected. A cut not given is the paper's (z0, rho in cm; energies as fractions of the beam "
      "energy, MeV).");
}

}  // namespace emcalign::python
