#pragma once
// The hemisphere placements of an alignment, for a simulation (docs/contract.md §9, §11; docs/apply.md).
//
// An alignment moves each hemisphere of each support sphere rigidly: p1 = R·p0 + t, p0 in
// the nominal EMC frame, p1 in the TS frame (geometry/alignment_transform.hpp). Support
// sphere 1 carries layers 1–2 with the transform of docs/contract.md §4; support sphere 2 carries
// layer 3, with μ replaced by μ3 when the layer-3 rule applies. Four placements in all.
//
// JSON (`emcalign-placements/1`):
//   {"format": "emcalign-placements/1", "alignment": {the parameter file},
//    "placements": [{"support": 1|2, "hemisphere": 1|-1, "rotation": [[3], [3], [3]] (row
//                    major), "translation_cm": [x, y, z]}, … four of them]}
//
// GDML: one <physvol> per placement, named sphere1_plus, sphere1_minus, sphere2_plus,
// sphere2_minus, in Geant4's convention, which is the *frame* rotation:
//   - G4GDMLReadDefine::GetRotationMatrix builds M from the angles (x, y, z) with
//     rot.rotateX(x); rot.rotateY(y); rot.rotateZ(z), i.e. M = Rz(z)·Ry(y)·Rx(x) (CLHEP's
//     rotateX multiplies from the left);
//   - G4GDMLReadStructure::PhysvolRead places the volume with G4Transform3D(M.inverse(),
//     position): a daughter point p goes to M⁻¹·p + position in the mother.
// So the written angles are those of M = Rᵀ (decomposed as G4GDMLWriteDefine::GetAngles
// does), the position is t, and lengths are in mm, angles in deg.

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/counter_geometry.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::apply {

inline constexpr std::string_view kPlacementsFormat = "emcalign-placements/1";

struct Placement {
  int support = 1;  ///< 1: layers 1–2, 2: layer 3
  geometry::Hemisphere hemisphere = geometry::Hemisphere::Plus;
  geometry::RigidTransform transform;  ///< p1 = rotation·p0 + translation (cm)
  /// sphere1_plus, sphere1_minus, sphere2_plus, sphere2_minus
  [[nodiscard]] std::string name() const;
};

struct Placements {
  geometry::AlignmentParameters alignment;
  std::array<Placement, 4> placements;  ///< (1, +), (1, −), (2, +), (2, −)
};

/// The placements of an alignment on a detector.
Placements placementsOf(const geometry::AlignmentTransform& transform);

/// The angles (x, y, z), rad, with M = Rz(z)·Ry(y)·Rx(x) (G4GDMLWriteDefine::GetAngles).
Vec3 gdmlAngles(const Mat3& m);
/// M = Rz(z)·Ry(y)·Rx(x) (G4GDMLReadDefine::GetRotationMatrix).
Mat3 gdmlMatrix(const Vec3& angles);

io::Json placementsJson(const Placements& p);
/// A GDML document: a world, the four hemisphere shells (G4Sphere envelopes of the layers
/// they carry, NIST materials G4_NaI and G4_Galactic) and their four <physvol>.
std::string placementsGdml(const Placements& p, const geometry::DetectorDescription& d);
/// The file `emcalign export` writes of `transform`'s placements: `format` "gdml"
/// (placementsGdml), else "json" (placementsJson, indented, with a final newline).
std::string placementsFile(const geometry::AlignmentTransform& transform, const geometry::DetectorDescription& d,
                           std::string_view format);
/// The line `emcalign export` prints: what was written (`output`, "-": standard output), in
/// which format, and whether layer 3 follows the μ3 rule (docs/contract.md §4).
std::string placementsWrittenText(const std::string& output, std::string_view format, bool layer3Rule);

/// Reads a placements file; checks that its placements are those of its alignment on this
/// detector (to 1e-9 cm and rad): an edited placement would not be what a fit means.
Result<Placements> readPlacements(const std::string& path, const geometry::Calorimeter& calo);
/// Whether a JSON document is a placements file (by its "format").
bool isPlacementsJson(const io::Json& j);

/// An alignment from any of the files that hold one: a parameter file, a fit result (a
/// usable one: io/json_files.hpp), or a placements file (checked against its own alignment).
/// The warnings are for the caller to show.
Result<io::AlignmentFile> loadAlignment(const std::string& path, const geometry::Calorimeter& calo);

/// The counters placed by the alignment of `path` (loadAlignment: its warnings into `warnings`),
/// or nominal when `path` is empty.
Result<geometry::CounterGeometry> countersOf(const geometry::Calorimeter& calo, const std::string& path,
                                             std::vector<std::string>& warnings);

}  // namespace emcalign::apply
