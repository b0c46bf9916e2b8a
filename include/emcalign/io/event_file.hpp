#pragma once
// Event files (docs/contract.md §6): one row per reconstructed particle, the rows of an event
// contiguous, in CSV (interchange) or HDF5 (bulk, columnar, chunked, compressed, with
// optional simulation truth). The format is chosen by the file name: ".csv" is CSV,
// anything else HDF5.
//
// CSV columns, in this order, header line required, '#' lines are comments:
//   run,event,beam_energy_mev,muon_veto,charged,z0_cm,rho_cm,phi_ts_rad,theta_ts_rad,
//   energy_mev,phi_emc_rad,theta_emc_rad
// charged = 1: a TS track and its matched EMC cluster (the cluster fields empty if none);
// charged = 0: a photon (an EMC cluster; the track fields empty). In memory and in HDF5 an
// empty field is NaN; a NaN (or "nan" text) where a value is required is an error.
//
// Readers are strict and streaming: memory does not grow with the rows. The check below
// keeps a few bytes per file whose events are numbered without gaps, 24 bytes per gap in
// the numbering, 16–32 bytes per event when the events come in no order. Every refused
// input is reported with the file, the line (CSV) or record (HDF5) and the column. HDF5
// files are read in a child process (libhdf5 crashes and loops on some corrupted files;
// io/isolated_source.cpp).
// Writers follow io/output_file.hpp: a temporary next to the target renamed on `close()`
// (a writer destroyed without a successful close removes it, so a failed or interrupted
// job leaves no partial file); a device, a FIFO or "-" (standard output, CSV) is written
// directly.
//
// What a row must satisfy (readers refuse it, writers refuse to append it):
//   run (int32), event (int64), muon_veto and charged (0 or 1) are integers, never empty;
//   beam_energy_mev > 0; no infinities; phi_* in [0, 2π], theta_* in [0, π] (bounds
//   included); energy_mev >= 0; charged = 1 has all four track fields; charged = 0 has no
//   track field and a cluster; the three cluster fields are all filled or all empty; the
//   rows of one event (consecutive rows with the same run and event) share beam_energy_mev
//   and muon_veto. CSV numbers must spell the whole field: "nan"/"inf" text is refused
//   (an empty field is the missing value) and "1.0" or "1e3" is not an integer.
// Hits (HDF5 only; CSV has none and reads as hitCount 0): a row without a cluster has none,
//   a row with a cluster at least one and at most kMaxHitsPerRow; offsets follow each other
//   from 0 without holes; counters are ≥ 0 and energies finite and ≥ 0 (the counter's range
//   is the detector's to check).
// Across rows (readers only): an event — a (run, event) pair — appears once, its rows
//   contiguous, in all the files of one reader together (a file given twice, a copy, a
//   repeated event or an event's rows apart are refused, naming both places; the same file
//   twice is refused by name before reading), and has at most 1000 rows.
//
// CSV text: '# key: value' comment lines before the header are the attributes; other
// comments and blank lines are skipped anywhere; CRLF is accepted; a row must end with a
// newline (a file cut inside its last field would otherwise read as a valid number).
// Written numbers use 17 significant digits ({:.17g}), so they read back bit for bit; NaN
// is written as an empty field.
//
// HDF5 layout (little-endian types, every dataset 1-D, chunked 16384 rows, unlimited,
// shuffle + LZ4, the HDF5 filter 32004 of Debian's hdf5-filter-plugin; any other layout and
// filter HDF5 can read is read too, e.g. deflate):
//   /events/run int32, event int64, beam_energy_mev double, muon_veto int8, charged int8,
//           z0_cm, rho_cm, phi_ts_rad, theta_ts_rad, energy_mev, phi_emc_rad,
//           theta_emc_rad double (NaN = empty field)
//   /truth/pdg int32, energy_mev, theta_rad, phi_rad, vertex_{x,y,z}_cm,
//          shower_{x,y,z}_cm double (optional; same length as /events; values unchecked)
//   Hits (optional, both or neither): /events/hit_offset int64 and /events/hit_count int32
//          per row, /hits/counter int32 and /hits/energy_mev double, flat in row order;
//          a row's hits are /hits[hit_offset, hit_offset + hit_count).
//   root attributes: scalar variable-length UTF-8 strings, in creation order.
// The file holds no timestamps (object time tracking is off): the same rows and
// attributes give the same file, byte for byte, however they were split into appends.
// The reader accepts any layout (chunked or not, any byte order) but exactly these names
// and types: a missing, extra, mistyped or shorter dataset is an error, and root
// attributes that are not strings are skipped. HDF5's own error printing is switched off
// during every call (and restored after); its reason is put into the returned message.

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "emcalign/core/event_record.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::io {

/// The CSV header line (without newline).
extern const char* const kCsvHeader;

/// The most counters one cluster row may have (a shower fires a few dozen).
inline constexpr int kMaxHitsPerRow = 2000;

enum class EventFormat { Csv, Hdf5 };

/// HDF5 compression: shuffle + LZ4 (the filter 32004: fast; h5py needs Debian's
/// hdf5-filter-plugin or pip's hdf5plugin to read it), or shuffle + deflate (every HDF5
/// reader has it: for files sent to others; 10 % smaller, written 2× slower).
enum class Compression { Lz4, Deflate };
EventFormat formatOf(const std::string& path);
/// The format of an output made from `input`'s events: by the output's name when it says one
/// (".csv", "-": CSV; ".h5", ".hdf5": HDF5), else the input's (a CSV corrected into a CSV).
EventFormat outputFormatOf(const std::string& output, const std::string& input);

struct WriterOptions {
  bool withTruth = false;  ///< HDF5 only; ignored (no truth written) for CSV
  /// Free-form metadata stored as HDF5 string attributes of the root group (e.g.
  /// "truth_parameters" → alignment JSON, "generator" → settings JSON); for CSV, written as
  /// '# key: value' comment lines before the header. Keys are made of letters, digits,
  /// '_', '.' and '-' and given once; values hold no NUL and, for CSV, no line break
  /// (compact JSON is fine). `open` refuses anything else.
  std::vector<std::pair<std::string, std::string>> attributes;
  bool withHits = false;                       ///< HDF5 only; ignored (no hits written) for CSV
  Compression compression = Compression::Lz4;  ///< HDF5 only
  /// A file a command writes inside its output directory (a period's runs): a FIFO or a device
  /// there is refused (io/output_file.hpp).
  Placement placement = Placement::Named;
};

/// Writes `path` by the rules of io/output_file.hpp: through the temporary `<path>.tmp-<pid>`
/// (so a second writer of one path in one process is refused), or directly to a device,
/// a FIFO or "-". Memory is bounded: rows are buffered and written in blocks.
class EventWriter {
 public:
  static Result<std::unique_ptr<EventWriter>> open(const std::string& path, const WriterOptions& options);
  /// The same in `format`, whatever the name says.
  static Result<std::unique_ptr<EventWriter>> open(const std::string& path, const WriterOptions& options,
                                                   EventFormat format);
  virtual ~EventWriter() = default;
  /// Appends rows, checked by the rules above (an event may continue into the next append).
  /// With withTruth (HDF5), `truth` must have one row per row; otherwise it is ignored.
  /// With withHits (HDF5), `hits` holds the rows' hits in row order (Σ hitCount of them);
  /// otherwise hits and hitCount are ignored (written as none).
  /// A refused append writes none of its rows and fails the writer for good: every later
  /// call fails and no file is produced, so a job that ignores the error cannot leave a
  /// file with rows missing.
  virtual Status append(std::span<const ParticleRow> rows, std::span<const TruthRow> truth,
                        std::span<const Hit> hits = {}) = 0;
  /// Flushes and renames the temporary into place. Must be called for the file to exist.
  virtual Status close() = 0;
};

struct ReaderOptions {
  std::size_t blockRows = 65536;  ///< rows per read (memory bound); at least 1
  /// HDF5 files are read in a child process (libhdf5 crashes or loops on some corrupted
  /// files): one silent for this long is killed and the file reported as unreadable.
  double hdf5TimeoutSeconds = 60.0;
  /// Whether to read the truth and the hits of files that have them. A reader that needs
  /// neither (the fit: selection and profiles) reads only /events: a third of the bytes of
  /// a simulated file with hits. What is not read is not checked, and truth()/hits() are null.
  bool truth = true;
  bool hits = true;
};

/// The rules above for rows that never were a file (the Python module's numpy columns, an
/// experiment's ntuple): each row's values, the rows of an event contiguous with one beam
/// energy and muon veto, at most 1000 of them, each event once. The error names `source`, the
/// row (0-based), its run and event and the column: "events: row 12 (run 1, event 7): column
/// 'theta_emc_rad': …".
Status checkRowsInMemory(std::span<const ParticleRow> rows, const std::string& source);

/// The beam energy of the first event of the files (MeV): what a sample of one energy is at,
/// before it is read (a corrections grid interpolates to it). Fails when there is no event.
Result<double> firstBeamEnergy(const std::vector<std::string>& paths);

/// For each of `keys`, the value of that attribute when every file has it, the same (a
/// simulated sample's "truth_parameters"); none when a file lacks it or two differ (the runs
/// of a period). Each file is opened once.
Result<std::map<std::string, std::optional<std::string>>> commonAttributes(const std::vector<std::string>& paths,
                                                                           const std::vector<std::string>& keys);

/// Streams rows from one or several files in order. `open` checks that every file exists
/// (a missing last file is reported at once, not after reading the others) and opens the
/// first one (so its attributes are known and a bad header is reported by `open`).
class EventReader {
 public:
  static Result<std::unique_ptr<EventReader>> open(std::vector<std::string> paths, ReaderOptions options = {});
  virtual ~EventReader() = default;
  /// Reads about blockRows rows into `rows` (cleared first), always whole events: a block
  /// ends at an event boundary (it may hold more than blockRows rows when one event is
  /// larger). Returns false at the end of the last file; an error for malformed input.
  /// A block never spans two files (the last block of a file may be short), so an event
  /// cut across two files comes out as two events. After an error every call returns it.
  virtual Result<bool> next(std::vector<ParticleRow>& rows) = 0;
  /// The file the last block came from.
  [[nodiscard]] virtual const std::string& path() const = 0;
  /// The truth rows matching the last block, when the current file has truth.
  [[nodiscard]] virtual const std::vector<TruthRow>* truth() const = 0;
  /// The hits of the last block in row order (row i's are the next rows[i].hitCount), when
  /// the current file has hits.
  [[nodiscard]] virtual const std::vector<Hit>* hits() const = 0;
  /// Metadata attributes of the file currently read (HDF5 attributes or CSV '# key:' lines).
  [[nodiscard]] virtual const std::vector<std::pair<std::string, std::string>>& attributes() const = 0;
};

}  // namespace emcalign::io
