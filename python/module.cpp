// The pybind11 module `emcalign._emcalign`: bindings only (STYLE.md). Arrays cross as numpy
// arrays, never as per-row Python objects; every library error becomes `emcalign.Error` with
// the message the command-line tool prints after "emcalign: error: ". Long loops release the
// GIL. Units are the library's (cm, MeV, rad) unless a name says otherwise.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <fmt/format.h>

#include <array>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/profiles.hpp"
#include "emcalign/calib/selection.hpp"
#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/counter_geometry.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/output_file.hpp"

namespace py = pybind11;
using namespace emcalign;

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

// The Python exception of every library error (created in the module init).
PyObject* gError = nullptr;

[[noreturn]] void raise(const Error& e) {
  PyErr_SetString(gError, e.message.c_str());
  throw py::error_already_set();
}

template <typename T>
T unwrap(Result<T> r) {
  if (!r) raise(r.error());
  return std::move(r.value());
}

void check(const Status& s) {
  if (!s) raise(s.error());
}

// The 12 fit parameters from a numpy vector (native units).
geometry::AlignmentParameters parametersOf(const Array& values) {
  if (values.ndim() != 1 || values.shape(0) != static_cast<py::ssize_t>(kNumParams)) {
    raise(Error{"parameters: expected 12 values (the fit set of SPEC §3, native units)"});
  }
  geometry::AlignmentParameters eta;
  for (std::size_t k = 0; k < kNumParams; ++k) eta.values[static_cast<Eigen::Index>(k)] = values.at(k);
  return eta;
}

Array arrayOf(const geometry::ParamVector& v) {
  Array out(static_cast<py::ssize_t>(kNumParams));
  for (std::size_t k = 0; k < kNumParams; ++k) out.mutable_at(k) = v[static_cast<Eigen::Index>(k)];
  return out;
}

// (N, 3) points in, checked.
py::ssize_t pointCount(const Array& points) {
  if (points.ndim() != 2 || points.shape(1) != 3) raise(Error{"points: expected an (N, 3) array of x, y, z in cm"});
  return points.shape(0);
}

Vec3 pointAt(const Array& points, py::ssize_t i) { return {points.at(i, 0), points.at(i, 1), points.at(i, 2)}; }

// The calorimeter and its nominal counters: the embedded SND-like detector or a description.
class Detector {
 public:
  explicit Detector(const std::optional<std::string>& path)
      : source_(path ? *path : "embedded default"), calo_(unwrap(io::loadCalorimeter(path.value_or("")))) {}

  [[nodiscard]] const geometry::Calorimeter& calorimeter() const { return calo_; }
  /// What a result file records as the detector: the path, or "embedded default".
  [[nodiscard]] const std::string& source() const { return source_; }

  // The counters as columns (SPEC §2 indexing): index, layer, ring, iphi, hemisphere, the
  // mid-angles θ, φ (rad) and the nominal centre (N, 3), cm.
  [[nodiscard]] py::dict counters() const {
    const auto n = static_cast<py::ssize_t>(calo_.size());
    py::array_t<int> layer(n), ring(n), iphi(n), hemisphere(n);
    Array theta(n), phi(n), centre({n, static_cast<py::ssize_t>(3)});
    for (py::ssize_t i = 0; i < n; ++i) {
      const auto& c = calo_.counter(static_cast<int>(i));
      layer.mutable_at(i) = c.layer;
      ring.mutable_at(i) = c.ring;
      iphi.mutable_at(i) = c.iphi;
      hemisphere.mutable_at(i) = geometry::sign(c.hemisphere);
      theta.mutable_at(i) = c.theta();
      phi.mutable_at(i) = c.phi();
      for (int k = 0; k < 3; ++k) centre.mutable_at(i, k) = c.centre()[k];
    }
    py::dict out;
    out["layer"] = layer;
    out["ring"] = ring;
    out["iphi"] = iphi;
    out["hemisphere"] = hemisphere;
    out["theta_rad"] = theta;
    out["phi_rad"] = phi;
    out["centre_cm"] = centre;
    return out;
  }

  // The counter centres in the TS frame with an alignment (the geometry database).
  [[nodiscard]] Array alignedCentres(const Array& values) const {
    const auto transform = unwrap(
        geometry::AlignmentTransform::create(parametersOf(values), geometry::AlignmentRadii::of(calo_.description())));
    const auto n = static_cast<py::ssize_t>(calo_.size());
    Array out({n, static_cast<py::ssize_t>(3)});
    auto w = out.mutable_unchecked<2>();
    {
      py::gil_scoped_release release;
      const auto g = geometry::CounterGeometry::aligned(calo_, transform);
      for (py::ssize_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) w(i, k) = g.centre(static_cast<int>(i))[k];
      }
    }
    return out;
  }

  // The counter containing each nominal-frame point, −1 where none.
  [[nodiscard]] py::array_t<int> locate(const Array& points) const {
    const py::ssize_t n = pointCount(points);
    py::array_t<int> out(n);
    auto r = points.unchecked<2>();
    auto w = out.mutable_unchecked<1>();
    py::gil_scoped_release release;
    for (py::ssize_t i = 0; i < n; ++i) {
      const auto at = calo_.locate({r(i, 0), r(i, 1), r(i, 2)});
      w(i) = at.region == geometry::Region::Counter ? at.counter : -1;
    }
    return out;
  }

 private:
  std::string source_;
  geometry::Calorimeter calo_;
};

// The transform of SPEC §4 on (N, 3) points, each in the hemisphere of its own x (nominal
// frame, forward) or as given; support "inner" or "outer" (layer 3).
Array transformPoints(const Detector& detector, const Array& values, const Array& points, bool forward,
                      const std::string& support, std::optional<int> hemisphere) {
  if (support != "inner" && support != "outer") raise(Error{"support: 'inner' or 'outer'"});
  if (hemisphere && *hemisphere != 1 && *hemisphere != -1) raise(Error{"hemisphere: +1, -1 or None"});
  if (!forward && !hemisphere) raise(Error{"inverse: give the hemisphere (+1 or -1) of the points"});
  const auto transform = unwrap(geometry::AlignmentTransform::create(
      parametersOf(values), geometry::AlignmentRadii::of(detector.calorimeter().description())));
  const py::ssize_t n = pointCount(points);
  const geometry::Support s = support == "outer" ? geometry::Support::Outer : geometry::Support::Inner;
  Array out({n, static_cast<py::ssize_t>(3)});
  auto r = points.unchecked<2>();
  auto w = out.mutable_unchecked<2>();
  py::gil_scoped_release release;
  for (py::ssize_t i = 0; i < n; ++i) {
    const Vec3 p{r(i, 0), r(i, 1), r(i, 2)};
    const geometry::Hemisphere h =
        hemisphere ? static_cast<geometry::Hemisphere>(*hemisphere) : geometry::hemisphereOf(p.x());
    const Vec3 q = forward ? transform.forward(p, h, s) : transform.inverse(p, h, s);
    for (int k = 0; k < 3; ++k) w(i, k) = q[k];
  }
  return out;
}

// An event file's rows as numpy columns (SPEC §6 names and units), with its truth and hits
// when it has them and they are asked for.
py::dict readEvents(const std::vector<std::string>& paths, bool truth, bool hits) {
  io::ReaderOptions o;
  o.truth = truth;
  o.hits = hits;
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truthRows;
  std::vector<Hit> hitRows;
  bool withTruth = truth, withHits = hits;
  {
    py::gil_scoped_release release;
    auto reader = io::EventReader::open(paths, o);
    if (!reader) {
      py::gil_scoped_acquire acquire;
      raise(reader.error());
    }
    std::vector<ParticleRow> block;
    while (true) {
      auto more = (*reader)->next(block);
      if (!more) {
        py::gil_scoped_acquire acquire;
        raise(more.error());
      }
      if (!*more) break;
      rows.insert(rows.end(), block.begin(), block.end());
      const auto* t = (*reader)->truth();
      const auto* h = (*reader)->hits();
      withTruth = withTruth && t != nullptr;
      withHits = withHits && h != nullptr;
      if (withTruth) truthRows.insert(truthRows.end(), t->begin(), t->end());
      if (withHits) hitRows.insert(hitRows.end(), h->begin(), h->end());
    }
  }
  const auto n = static_cast<py::ssize_t>(rows.size());
  py::dict out;
  const auto column = [&](const char* key, auto field) {
    using V = std::decay_t<decltype(field(rows[0]))>;
    py::array_t<V> a(n);
    auto w = a.template mutable_unchecked<1>();
    for (py::ssize_t i = 0; i < n; ++i) w(i) = field(rows[static_cast<std::size_t>(i)]);
    out[key] = a;
  };
  column("run", [](const ParticleRow& r) { return r.run; });
  column("event", [](const ParticleRow& r) { return r.event; });
  column("beam_energy_mev", [](const ParticleRow& r) { return r.beamEnergy; });
  column("muon_veto", [](const ParticleRow& r) { return r.muonVeto; });
  column("charged", [](const ParticleRow& r) { return r.charged; });
  column("z0_cm", [](const ParticleRow& r) { return r.z0; });
  column("rho_cm", [](const ParticleRow& r) { return r.rho; });
  column("phi_ts_rad", [](const ParticleRow& r) { return r.phiTs; });
  column("theta_ts_rad", [](const ParticleRow& r) { return r.thetaTs; });
  column("energy_mev", [](const ParticleRow& r) { return r.energy; });
  column("phi_emc_rad", [](const ParticleRow& r) { return r.phiEmc; });
  column("theta_emc_rad", [](const ParticleRow& r) { return r.thetaEmc; });
  if (withHits) column("hit_count", [](const ParticleRow& r) { return r.hitCount; });
  if (withTruth && truthRows.size() == rows.size()) {
    py::dict t;
    const auto tn = static_cast<py::ssize_t>(truthRows.size());
    py::array_t<std::int32_t> pdg(tn);
    Array energy(tn), theta(tn), phi(tn), vertex({tn, static_cast<py::ssize_t>(3)}),
        shower({tn, static_cast<py::ssize_t>(3)});
    for (py::ssize_t i = 0; i < tn; ++i) {
      const TruthRow& r = truthRows[static_cast<std::size_t>(i)];
      pdg.mutable_at(i) = r.pdg;
      energy.mutable_at(i) = r.energy;
      theta.mutable_at(i) = r.theta;
      phi.mutable_at(i) = r.phi;
      for (int k = 0; k < 3; ++k) {
        vertex.mutable_at(i, k) = r.vertex[k];
        shower.mutable_at(i, k) = r.showerCentre[k];
      }
    }
    t["pdg"] = pdg;
    t["energy_mev"] = energy;
    t["theta_rad"] = theta;
    t["phi_rad"] = phi;
    t["vertex_cm"] = vertex;
    t["shower_centre_cm"] = shower;
    out["truth"] = t;
  }
  if (withHits) {
    const auto hn = static_cast<py::ssize_t>(hitRows.size());
    py::array_t<std::int32_t> counter(hn);
    Array energy(hn);
    for (py::ssize_t i = 0; i < hn; ++i) {
      counter.mutable_at(i) = hitRows[static_cast<std::size_t>(i)].counter;
      energy.mutable_at(i) = hitRows[static_cast<std::size_t>(i)].energy;
    }
    py::dict h;
    h["counter"] = counter;
    h["energy_mev"] = energy;
    out["hits"] = h;
  }
  return out;
}

// A column of the dict read_events gives (or any dict of the same columns), as doubles.
std::vector<double> columnOf(const py::dict& events, const char* key, std::size_t n) {
  if (!events.contains(key)) raise(Error{fmt::format("events: no column '{}' (a dict as read_events gives)", key)});
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(events[key]);
  if (!a || a.ndim() != 1 || static_cast<std::size_t>(a.shape(0)) != n) {
    raise(Error{fmt::format("events: column '{}' is not a 1-D array of {} rows", key, n)});
  }
  return {a.data(), a.data() + n};
}

// SPEC §7's selection on the rows of `events`: per row, the index (1..5, CutFlow::kNames) of
// the first cut its event fails, 0 when the event is selected. An event is its consecutive
// rows of one (run, event).
py::array_t<int> selectRows(const py::dict& events, const calib::SelectionOptions& options) {
  if (!events.contains("run")) raise(Error{"events: no column 'run' (a dict as read_events gives)"});
  const auto n = static_cast<std::size_t>(py::len(events["run"]));
  const auto run = columnOf(events, "run", n), event = columnOf(events, "event", n);
  const auto beam = columnOf(events, "beam_energy_mev", n), veto = columnOf(events, "muon_veto", n);
  const auto charged = columnOf(events, "charged", n), z0 = columnOf(events, "z0_cm", n);
  const auto rho = columnOf(events, "rho_cm", n), phiTs = columnOf(events, "phi_ts_rad", n);
  const auto thetaTs = columnOf(events, "theta_ts_rad", n), energy = columnOf(events, "energy_mev", n);
  const auto phiEmc = columnOf(events, "phi_emc_rad", n), thetaEmc = columnOf(events, "theta_emc_rad", n);
  py::array_t<int> out(static_cast<py::ssize_t>(n));
  auto w = out.mutable_unchecked<1>();
  py::gil_scoped_release release;
  std::vector<ParticleRow> rows(n);
  for (std::size_t i = 0; i < n; ++i) {
    ParticleRow& r = rows[i];
    r.run = static_cast<std::int32_t>(run[i]);
    r.event = static_cast<std::int64_t>(event[i]);
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
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i + 1;
    while (j < n && sameEvent(rows[j], rows[i])) ++j;
    const int cut = calib::selectEvent(std::span<const ParticleRow>(rows.data() + i, j - i), options);
    for (std::size_t k = i; k < j; ++k) w(static_cast<py::ssize_t>(k)) = cut;
    i = j;
  }
  return out;
}

// Profile bins as numpy columns (the profile file's, SPEC §8), plus `used`.
py::dict binColumns(const std::vector<calib::ProfileBin>& bins) {
  const auto n = static_cast<py::ssize_t>(bins.size());
  py::array_t<int> iPhi(n), iTheta(n);
  py::array_t<std::int64_t> entries(n);
  py::array_t<bool> used(n);
  Array phi(n), theta(n), energy(n), yPhi(n), sigmaPhi(n), yTheta(n), sigmaTheta(n), plusWeight(n);
  for (py::ssize_t i = 0; i < n; ++i) {
    const calib::ProfileBin& b = bins[static_cast<std::size_t>(i)];
    iPhi.mutable_at(i) = b.iPhi;
    iTheta.mutable_at(i) = b.iTheta;
    entries.mutable_at(i) = b.n;
    used.mutable_at(i) = b.used;
    phi.mutable_at(i) = b.phiMean;
    theta.mutable_at(i) = b.thetaMean;
    energy.mutable_at(i) = b.energyMean;
    yPhi.mutable_at(i) = b.yPhi;
    sigmaPhi.mutable_at(i) = b.sigmaPhi;
    yTheta.mutable_at(i) = b.yTheta;
    sigmaTheta.mutable_at(i) = b.sigmaTheta;
    plusWeight.mutable_at(i) = b.plusWeight;
  }
  py::dict d;
  d["i_phi"] = iPhi;
  d["i_theta"] = iTheta;
  d["n"] = entries;
  d["phi_mean_rad"] = phi;
  d["theta_mean_rad"] = theta;
  d["e_mean_mev"] = energy;
  d["y_phi"] = yPhi;
  d["sigma_phi"] = sigmaPhi;
  d["y_theta"] = yTheta;
  d["sigma_theta"] = sigmaTheta;
  d["plus_weight"] = plusWeight;
  d["used"] = used;
  return d;
}

// A fit of event files as `emcalign fit FILES -o RESULT --profile-out PROFILE` makes it
// (SPEC §7–§8, without --corrections): the result, its file's text and the profile's.
struct EventFit {
  calib::ProfileFill fill;
  calib::FitResult result;
  std::vector<calib::ProfileBin> bins;
  std::string json;        ///< the result file, byte for byte the CLI's
  std::string profileCsv;  ///< the --profile-out file
};

EventFit fitEvents(const std::vector<std::string>& paths, const Detector& detector, const py::object& sigmaSys,
                   std::optional<double> beamEnergy, double depthOffset) {
  calib::SigmaSysChoice choice = calib::SigmaSysChoice::spec();
  if (py::isinstance<py::str>(sigmaSys)) {
    if (sigmaSys.cast<std::string>() != "auto") raise(Error{"sigma_sys: None (SPEC's 0.2 deg), 'auto' or degrees"});
    choice = calib::SigmaSysChoice::automatic();
  } else if (!sigmaSys.is_none()) {
    choice = calib::SigmaSysChoice::fixed(sigmaSys.cast<double>() * units::deg);
  }
  check(choice.validate());
  if (beamEnergy && !(*beamEnergy > 0.0)) raise(Error{"beam_energy: a positive energy in MeV, or None"});
  EventFit out;
  Status failed;
  {
    py::gil_scoped_release release;
    calib::FitGeometry geometry = calib::FitGeometry::of(detector.calorimeter().description());
    geometry.depth.offset = depthOffset * units::cm;
    calib::ProfileOptions profile;
    profile.eventPairs = choice.keepsEventPairs();
    calib::SelectionOptions selection;
    if (beamEnergy) selection.beamEnergy = *beamEnergy;
    auto filled = calib::fillProfiles(paths, geometry.depth, selection, profile);
    if (filled) {
      out.fill = std::move(*filled);
      auto result = calib::fitProfiles(out.fill.profiles, geometry, choice);
      if (result) {
        out.result = std::move(*result);
        out.bins = calib::fittedBins(out.fill.profiles, out.result.sigmaSys);
        calib::FitInput input;
        input.files = paths;
        input.fill = &out.fill;
        input.detector = detector.source();
        input.depthOffset = depthOffset * units::cm;
        out.json = calib::fitResultJson(out.result, input).dump(2) + "\n";
        out.profileCsv = calib::profileCsv(out.bins);
      } else {
        failed = result.error();
      }
    } else {
      failed = filled.error();
    }
  }
  check(failed);
  return out;
}

py::dict derivedOf(const calib::FitResult& r) {
  py::dict d;
  for (Physical p : kDerivedParams)
    d[py::str(std::string(name(p)))] = py::make_tuple(r.derived[p].value, r.derived[p].error);
  return d;
}

py::object matrixOf(const geometry::ParamMatrix& m) {
  const auto n = static_cast<py::ssize_t>(kNumParams);
  Array out({n, n});
  for (py::ssize_t i = 0; i < n; ++i) {
    for (py::ssize_t j = 0; j < n; ++j) out.mutable_at(i, j) = m(i, j);
  }
  return std::move(out);
}

}  // namespace

PYBIND11_MODULE(_emcalign, m) {
  m.doc() = "emcalign: the geometric calibration of a two-hemisphere calorimeter (C++ library bindings)";
  gError = PyErr_NewExceptionWithDoc("emcalign.Error",
                                     "A refused input or a failed step; the message is the command-line tool's.",
                                     PyExc_RuntimeError, nullptr);
  m.attr("Error") = py::handle(gError);

  std::vector<std::string> params, physical;
  for (Param p : kAllParams) params.emplace_back(name(p));
  for (Physical p : kAllPhysical) physical.emplace_back(name(p));
  m.attr("PARAMETERS") = params;
  m.attr("PHYSICAL") = physical;
  m.attr("DERIVED") = [] {
    std::vector<std::string> d;
    for (Physical p : kDerivedParams) d.emplace_back(name(p));
    return d;
  }();
  m.def(
      "file_units",
      [] {
        Array out(static_cast<py::ssize_t>(kNumParams));
        for (Param p : kAllParams) out.mutable_at(index(p)) = geometry::AlignmentParameters::fileUnit(p);
        return out;
      },
      "native = file value × file_units()[k]: degrees for angles (and beta1, beta2), cm for lengths");

  py::class_<Detector>(m, "Detector", "The calorimeter: the embedded SND-like detector, or a description file")
      .def(py::init<std::optional<std::string>>(), py::arg("path") = py::none())
      .def_property_readonly("size", [](const Detector& d) { return d.calorimeter().size(); })
      .def_property_readonly("r1", [](const Detector& d) { return d.calorimeter().description().r1(); })
      .def("counters", &Detector::counters, "the counters as numpy columns (SPEC §2 indexing)")
      .def("aligned_centres", &Detector::alignedCentres, py::arg("parameters"),
           "the counter centres (N, 3) in the TS frame placed by an alignment (native units)")
      .def("locate", &Detector::locate, py::arg("points"),
           "the counter containing each nominal-frame point (N, 3), -1 where none");

  m.def(
      "read_alignment",
      [](const std::string& path, const Detector& detector) {
        auto file = unwrap(io::readAlignmentFile(path, detector.calorimeter().description().r1()));
        return py::make_tuple(arrayOf(file.parameters.values), file.warnings);
      },
      py::arg("path"), py::arg("detector"),
      "(parameters, warnings): the fit set (12, native units) of a parameter or fit-result file, and the "
      "warnings the command-line tool prints for it");
  m.def(
      "write_alignment",
      [](const std::string& path, const Array& values, const Detector& detector) {
        const auto j =
            unwrap(io::alignmentToJsonWithPhysical(parametersOf(values), detector.calorimeter().description().r1()));
        check(io::writeOutputFile(path, j.dump(2) + "\n"));
      },
      py::arg("path"), py::arg("parameters"), py::arg("detector"),
      "writes a parameter file (SPEC §3: file units, with the physical set)");
  m.def(
      "to_physical",
      [](const Array& values, double r1) {
        const auto phys = unwrap(geometry::toPhysical(parametersOf(values), r1));
        Array out(static_cast<py::ssize_t>(kNumParams));
        for (std::size_t k = 0; k < kNumParams; ++k) out.mutable_at(k) = phys.values[k];
        return out;
      },
      py::arg("parameters"), py::arg("r1"), "fit set -> physical set (12, native units, order of PHYSICAL)");
  m.def(
      "from_physical",
      [](const Array& values, double r1) {
        if (values.ndim() != 1 || values.shape(0) != static_cast<py::ssize_t>(kNumParams)) {
          raise(Error{"physical: expected 12 values (SPEC §3, native units)"});
        }
        geometry::PhysicalParameters phys;
        for (std::size_t k = 0; k < kNumParams; ++k) phys.values[k] = values.at(k);
        return arrayOf(geometry::fromPhysical(phys, r1).values);
      },
      py::arg("physical"), py::arg("r1"), "physical set -> fit set (12, native units)");
  m.def(
      "forward",
      [](const Detector& d, const Array& values, const Array& points, const std::string& support,
         std::optional<int> hemisphere) { return transformPoints(d, values, points, true, support, hemisphere); },
      py::arg("detector"), py::arg("parameters"), py::arg("points"), py::arg("support") = "inner",
      py::arg("hemisphere") = py::none(),
      "nominal EMC frame -> TS frame (SPEC §4) for (N, 3) points; hemisphere: of each point's x unless given");
  m.def(
      "inverse",
      [](const Detector& d, const Array& values, const Array& points, int hemisphere, const std::string& support) {
        return transformPoints(d, values, points, false, support, hemisphere);
      },
      py::arg("detector"), py::arg("parameters"), py::arg("points"), py::arg("hemisphere"),
      py::arg("support") = "inner", "TS frame -> nominal EMC frame (SPEC §4) for (N, 3) points of one hemisphere");
  m.def("read_events", &readEvents, py::arg("paths"), py::arg("truth") = true, py::arg("hits") = true,
        "the rows of event files (HDF5 or CSV, SPEC §6) as a dict of numpy columns, with 'truth' and 'hits' "
        "dicts when the files have them");

  py::class_<EventFit>(m, "FitResult", "A fit of event files: what emcalign fit writes, as numbers and as its files")
      .def_property_readonly("parameters", [](const EventFit& f) { return arrayOf(f.result.parameters.values); })
      .def_property_readonly("errors", [](const EventFit& f) { return arrayOf(f.result.errors); })
      .def_property_readonly("covariance",
                             [](const EventFit& f) -> py::object {
                               if (!f.result.covariance) return py::none();
                               return matrixOf(*f.result.covariance);
                             })
      .def_property_readonly("correlation", [](const EventFit& f) { return matrixOf(f.result.correlation); })
      .def_property_readonly(
          "derived", [](const EventFit& f) { return derivedOf(f.result); },
          "{name: (value, error)} of DERIVED, native units")
      .def_property_readonly("chi2", [](const EventFit& f) { return f.result.chi2; })
      .def_property_readonly("ndf", [](const EventFit& f) { return f.result.ndf; })
      .def_property_readonly("p_value", [](const EventFit& f) { return f.result.pValue; })
      .def_property_readonly("bins_used", [](const EventFit& f) { return f.result.binsUsed; })
      .def_property_readonly("status", [](const EventFit& f) { return std::string(name(f.result.status)); })
      .def_property_readonly("warnings", [](const EventFit& f) { return f.result.warnings; })
      .def_property_readonly(
          "sigma_sys", [](const EventFit& f) { return f.result.sigmaSys.value; }, "rad")
      .def_property_readonly("cut_flow",
                             [](const EventFit& f) {
                               py::dict d;
                               for (std::size_t k = 0; k < calib::CutFlow::kNames.size(); ++k) {
                                 d[calib::CutFlow::kNames[k]] = f.fill.cutFlow.events[k];
                               }
                               return d;
                             })
      .def_property_readonly(
          "bins", [](const EventFit& f) { return binColumns(f.bins); },
          "the profile bins as the fit saw them (columns of the profile file, and 'used')")
      .def_property_readonly(
          "json", [](const EventFit& f) { return f.json; }, "the result file's text (emcalign fit -o)")
      .def_property_readonly(
          "profile_csv", [](const EventFit& f) { return f.profileCsv; },
          "the profile file's text (emcalign fit --profile-out)")
      .def(
          "write", [](const EventFit& f, const std::string& path) { check(io::writeOutputFile(path, f.json)); },
          py::arg("path"), "writes the result file");
  m.def("fit", &fitEvents, py::arg("paths"), py::arg("detector"), py::arg("sigma_sys") = py::none(),
        py::arg("beam_energy") = py::none(), py::arg("depth_offset") = 0.0,
        "selects, fills the profiles and fits, as emcalign fit PATHS does (sigma_sys: None for SPEC's 0.2 deg, "
        "'auto', or degrees; beam_energy: MeV, None for each event's; depth_offset: cm)");

  std::vector<std::string> cuts;
  for (const char* c : calib::CutFlow::kNames) cuts.emplace_back(c);
  m.attr("CUTS") = cuts;
  m.def(
      "select",
      [](const py::dict& events, std::optional<double> beamEnergy, std::optional<double> maxAbsZ0,
         std::optional<double> maxAbsRho, std::optional<double> minEnergyFraction,
         std::optional<double> maxEnergyFraction, std::optional<double> maxAcollinearityDeg) {
        calib::SelectionOptions o;  // SPEC §7's cuts, unless given
        o.beamEnergy = beamEnergy;
        if (maxAbsZ0) o.maxAbsZ0 = *maxAbsZ0 * units::cm;
        if (maxAbsRho) o.maxAbsRho = *maxAbsRho * units::cm;
        if (minEnergyFraction) o.minEnergyFraction = *minEnergyFraction;
        if (maxEnergyFraction) o.maxEnergyFraction = *maxEnergyFraction;
        if (maxAcollinearityDeg) o.maxAcollinearity = *maxAcollinearityDeg * units::deg;
        return selectRows(events, o);
      },
      py::arg("events"), py::kw_only(), py::arg("beam_energy") = py::none(), py::arg("max_abs_z0") = py::none(),
      py::arg("max_abs_rho") = py::none(), py::arg("min_energy_fraction") = py::none(),
      py::arg("max_energy_fraction") = py::none(), py::arg("max_acollinearity_deg") = py::none(),
      "SPEC §7's selection on the rows of read_events: per row, the index in CUTS of the first cut its event "
      "fails, 0 when selected. A cut not given is SPEC's (z0, rho in cm; energies as fractions of the beam "
      "energy, MeV).");
  m.def(
      "read_profile",
      [](const std::string& path) {
        auto bins = unwrap(calib::readProfileCsv(path));
        calib::markUsedBins(bins, calib::ProfileOptions{}.minEntries);
        return binColumns(bins);
      },
      py::arg("path"), "a profile file (emcalign fit --profile-out) as numpy columns");
}
