// The detector and its geometry database, parameter files, fit ↔ physical sets and the
// transform of docs/contract.md §4 on (N, 3) arrays.

#include <fmt/format.h>

#include <cmath>

#include "bindings.hpp"
#include "emcalign/apply/placements.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/counter_geometry.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::python {

namespace {

// The radius of support sphere 1 of a conversion: a positive length (cm).
double radiusOf(double r1) {
  if (!(std::isfinite(r1) && r1 > 0.0)) raise(Error{fmt::format("r1: {} cm is not a positive radius", r1)});
  return r1;
}

// (N, 3) points in, checked.
py::ssize_t pointCount(const Array& points) {
  if (points.ndim() != 2 || points.shape(1) != 3) raise(Error{"points: expected an (N, 3) array of x, y, z in cm"});
  return points.shape(0);
}

geometry::AlignmentTransform transformOf(const Detector& d, const Array& values) {
  return unwrap(geometry::AlignmentTransform::create(parametersOf(values),
                                                     geometry::AlignmentRadii::of(d.calorimeter().description())));
}

// The counters as columns (docs/conventions.md indexing): layer, ring, iphi, hemisphere, the
// mid-angles θ, φ (rad) and the nominal centre (N, 3), cm.
py::dict counters(const Detector& d) {
  const geometry::Calorimeter& calo = d.calorimeter();
  const auto n = static_cast<py::ssize_t>(calo.size());
  py::array_t<int> layer(n), ring(n), iphi(n), hemisphere(n);
  Array theta(n), phi(n), centre({n, static_cast<py::ssize_t>(3)});
  for (py::ssize_t i = 0; i < n; ++i) {
    const auto& c = calo.counter(static_cast<int>(i));
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
Array alignedCentres(const Detector& d, const Array& values) {
  const auto transform = transformOf(d, values);
  const auto n = static_cast<py::ssize_t>(d.calorimeter().size());
  Array out({n, static_cast<py::ssize_t>(3)});
  auto w = out.mutable_unchecked<2>();
  py::gil_scoped_release release;
  const auto g = geometry::CounterGeometry::aligned(d.calorimeter(), transform);
  for (py::ssize_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) w(i, k) = g.centre(static_cast<int>(i))[k];
  }
  return out;
}

// The counter containing each nominal-frame point, −1 where none.
py::array_t<int> locate(const Detector& d, const Array& points) {
  const py::ssize_t n = pointCount(points);
  py::array_t<int> out(n);
  auto r = points.unchecked<2>();
  auto w = out.mutable_unchecked<1>();
  py::gil_scoped_release release;
  for (py::ssize_t i = 0; i < n; ++i) {
    const auto at = d.calorimeter().locate({r(i, 0), r(i, 1), r(i, 2)});
    w(i) = at.region == geometry::Region::Counter ? at.counter : -1;
  }
  return out;
}

// The transform of docs/contract.md §4 on (N, 3) points, each in the hemisphere of its own x (nominal
// frame, forward) or as given; support "inner" or "outer" (layer 3).
Array transformPoints(const Detector& detector, const Array& values, const Array& points, bool forward,
                      const std::string& support, std::optional<int> hemisphere) {
  if (support != "inner" && support != "outer") raise(Error{"support: 'inner' or 'outer'"});
  if (hemisphere && *hemisphere != 1 && *hemisphere != -1) raise(Error{"hemisphere: +1, -1 or None"});
  if (!forward && !hemisphere) raise(Error{"inverse: give the hemisphere (+1 or -1) of the points"});
  const auto transform = transformOf(detector, values);
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

// The names of the parameter sets and the file units.
void defineNames(py::module_& m) {
  std::vector<std::string> params, physical, derived;
  for (Param p : kAllParams) params.emplace_back(name(p));
  for (Physical p : kAllPhysical) physical.emplace_back(name(p));
  for (Physical p : kDerivedParams) derived.emplace_back(name(p));
  m.attr("PARAMETERS") = params;
  m.attr("PHYSICAL") = physical;
  m.attr("DERIVED") = derived;
  m.def(
      "file_units",
      [] {
        Array out(static_cast<py::ssize_t>(kNumParams));
        for (Param p : kAllParams) out.mutable_at(index(p)) = geometry::AlignmentParameters::fileUnit(p);
        return out;
      },
      "native = file value × file_units()[k]: degrees for angles (and beta1, beta2), cm for lengths");
}

// The files of parameters, and the fit set to the physical set and back.
void defineParameterFiles(py::module_& m) {
  m.def(
      "read_alignment",
      [](const Path& path, const Detector& detector) {
        auto file = unwrap(apply::loadAlignment(pathString(path), detector.calorimeter()));
        return py::make_tuple(arrayOf(file.parameters.values), file.warnings);
      },
      py::arg("path"), py::arg("detector"),
      "(parameters, warnings): the fit set (12, native units) of a parameter file, a fit result or a placements "
      "file, and the warnings the command-line tool prints for it");
  m.def(
      "write_alignment",
      [](const Path& path, const Array& values, const Detector& detector) {
        const auto j = unwrap(io::alignmentToJsonWithPhysical(parametersOf(values), detector.r1()));
        check(io::writeOutputFile(pathString(path), j.dump(2) + "\n"));
      },
      py::arg("path"), py::arg("parameters"), py::arg("detector"),
      "writes a parameter file (docs/conventions.md: file units, with the physical set)");
  m.def(
      "to_physical",
      [](const Array& values, double r1) {
        const auto phys = unwrap(geometry::toPhysical(parametersOf(values), radiusOf(r1)));
        Array out(static_cast<py::ssize_t>(kNumParams));
        for (std::size_t k = 0; k < kNumParams; ++k) out.mutable_at(k) = phys.values[k];
        return out;
      },
      py::arg("parameters"), py::arg("r1"), "fit set -> physical set (12, native units, order of PHYSICAL)");
  m.def(
      "from_physical",
      [](const Array& values, double r1) {
        if (values.ndim() != 1 || values.shape(0) != static_cast<py::ssize_t>(kNumParams)) {
          raise(Error{"physical: expected 12 values (docs/conventions.md, native units)"});
        }
        geometry::PhysicalParameters phys;
        for (std::size_t k = 0; k < kNumParams; ++k) phys.values[k] = values.at(k);
        return arrayOf(geometry::fromPhysical(phys, radiusOf(r1)).values);
      },
      py::arg("physical"), py::arg("r1"), "physical set -> fit set (12, native units)");
}

// The alignment transform of points, both ways (docs/conventions.md).
void defineTransforms(py::module_& m) {
  m.def(
      "forward",
      [](const Detector& d, const Array& values, const Array& points, const std::string& support,
         std::optional<int> hemisphere) { return transformPoints(d, values, points, true, support, hemisphere); },
      py::arg("detector"), py::arg("parameters"), py::arg("points"), py::arg("support") = "inner",
      py::arg("hemisphere") = py::none(),
      "nominal EMC frame -> TS frame (docs/conventions.md) for (N, 3) points; hemisphere: of each point's x unless "
      "given");
  m.def(
      "inverse",
      [](const Detector& d, const Array& values, const Array& points, int hemisphere, const std::string& support) {
        return transformPoints(d, values, points, false, support, hemisphere);
      },
      py::arg("detector"), py::arg("parameters"), py::arg("points"), py::arg("hemisphere"),
      py::arg("support") = "inner",
      "TS frame -> nominal EMC frame (docs/conventions.md) for (N, 3) points of one hemisphere");
}

}  // namespace

void bindGeometry(py::module_& m) {
  defineNames(m);
  py::class_<Detector>(m, "Detector", "The calorimeter: the embedded SND-like detector, or a description file")
      .def(py::init<std::optional<Path>>(), py::arg("path") = py::none())
      .def_property_readonly("size", [](const Detector& d) { return d.calorimeter().size(); })
      .def_property_readonly("r1", &Detector::r1)
      .def("counters", &counters, "the counters as numpy columns (docs/conventions.md indexing)")
      .def("aligned_centres", &alignedCentres, py::arg("parameters"),
           "the counter centres (N, 3) in the TS frame placed by an alignment (native units)")
      .def("locate", &locate, py::arg("points"),
           "the counter containing each nominal-frame point (N, 3), -1 where none");
  defineParameterFiles(m);
  defineTransforms(m);
}

}  // namespace emcalign::python
