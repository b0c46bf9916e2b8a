// The conditions database: calibrations stored by run range in tags (conddb/, docs/campaign.md).

#include <fmt/format.h>

#include "bindings.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/conddb/tag_tables.hpp"

namespace emcalign::python {

namespace {

// An integer of Python or numpy (not a bool), or nothing.
std::optional<std::int64_t> runOf(const py::handle& v) {
  if (PyBool_Check(v.ptr()) || !PyIndex_Check(v.ptr())) return std::nullopt;
  const auto index = py::reinterpret_steal<py::object>(PyNumber_Index(v.ptr()));
  if (!index) throw py::error_already_set();
  const long long n = PyLong_AsLongLong(index.ptr());
  if (n == -1 && PyErr_Occurred()) throw py::error_already_set();
  return n;
}

// The GIL is held throughout: a database connection is not shared between threads (libpqxx's
// is not thread-safe), and every call is short.
class Conditions {
 public:
  // A URI (sqlite:PATH, postgresql://…) or the path of an SQLite file.
  Conditions(const std::variant<std::string, Path>& uri, bool create)
      : db_(unwrap(conddb::Database::open(
            std::holds_alternative<Path>(uri) ? pathString(std::get<Path>(uri)) : std::get<std::string>(uri),
            create ? conddb::IfMissing::Create : conddb::IfMissing::Refuse))) {}

  [[nodiscard]] const std::string& uri() const { return db_->uri(); }

  // Every tag, or one, as `conditions list --json` shows them.
  py::object tags(const std::string& name) {
    const std::vector<conddb::TagListing> listed = unwrap(conddb::listTags(*db_, name));
    if (!name.empty()) return pythonOf(conddb::tagJson(listed.front()));
    py::list out;
    for (const auto& t : listed) out.append(pythonOf(conddb::tagJson(t)));
    return out;
  }

  // The calibration of `run`: {"parameters" (12, native), "first_run", "last_run", "payload",
  // "inserted", "file": the parameter file's text as `conditions get -o` writes it}.
  py::dict get(const std::string& tag, std::int64_t run, const Detector* given) {
    const Detector& detector = detectorOr(given);
    const conddb::RunCalibration c = unwrap(conddb::calibrationAt(*db_, tag, run));
    const auto eta =
        unwrap(io::parseAlignment(c.parameterFile, detector.r1(),
                                  fmt::format("{} tag {} IOV {}-{}", db_->uri(), tag, c.iov.firstRun, c.iov.lastRun)));
    py::dict d;
    d["parameters"] = arrayOf(eta.values);
    d["first_run"] = c.iov.firstRun;
    d["last_run"] = c.iov.lastRun;
    d["payload"] = c.iov.payload;
    d["inserted"] = c.iov.inserted;
    d["file"] = c.parameterFile.dump(2) + "\n";
    return d;
  }

  // Stores a fit result or parameter file for runs [first, last].
  py::dict put(const std::string& tag, const py::object& runs, const Path& path, const std::string& description,
               const Detector* given) {
    std::int64_t first = 0, last = 0;
    if (const auto one = runOf(runs)) {
      first = last = *one;
    } else {
      const auto pair = py::isinstance<py::sequence>(runs) && !py::isinstance<py::str>(runs) && py::len(runs) == 2
                            ? std::pair{runOf(runs[py::int_(0)]), runOf(runs[py::int_(1)])}
                            : std::pair<std::optional<std::int64_t>, std::optional<std::int64_t>>{};
      if (!pair.first || !pair.second) throw py::type_error("runs: a run number or (first, last)");
      first = *pair.first;
      last = *pair.second;
    }
    if (first < 0 || first > last) {
      raise(Error{fmt::format("runs ({}, {}): expected (first, last) with 0 <= first <= last", first, last)});
    }
    check(conddb::checkTagName(tag));
    const double r1 = detectorOr(given).r1();
    const conddb::PutReport report = unwrap(conddb::putResultFile(*db_, {.tag = tag,
                                                                         .firstRun = first,
                                                                         .lastRun = last,
                                                                         .path = pathString(path),
                                                                         .description = description,
                                                                         .r1 = r1}));
    py::dict d;
    d["payload"] = report.payload;
    d["new_tag"] = report.newTag;
    d["warnings"] = report.warnings;
    return d;
  }

  void lock(const std::string& tag) { check(db_->lock(tag)); }

  void retire(const std::string& tag, const std::string& reason) { check(db_->retire(tag, reason)); }

  // A tag's state, or (with `to`) a transition: conditions state [--set].
  std::string state(const std::string& tag, const std::optional<std::string>& to, const std::string& reason) {
    if (to) {
      const auto s = conddb::tagStateNamed(*to);
      if (!s)
        raise(Error{fmt::format("'{}' is no tag state: open, testing, validated, published, running or invalid", *to)});
      unwrap(db_->setState(tag, *s, reason));
    }
    auto t = unwrap(db_->tag(tag));
    if (!t) raise(Error{fmt::format("{}: no tag '{}'", db_->uri(), tag)});
    return std::string(conddb::name(t->state));
  }

  // conditions history --json.
  py::object history(const std::string& tag) {
    py::list out;
    for (const conddb::Change& c : unwrap(db_->history(tag))) out.append(pythonOf(c.json()));
    return out;
  }

  // conditions promote: {"from", "to", "first_safe_run", "last_iov_was", "last_iov_fate", "appended", "time"}.
  py::dict promote(const std::string& from, const std::string& to, std::int64_t firstSafeRun, bool dryRun) {
    const conddb::Database::Promotion p = unwrap(db_->promote(from, to, firstSafeRun, dryRun));
    py::dict d;
    d["from"] = p.from;
    d["to"] = p.to;
    d["first_safe_run"] = p.firstSafeRun;
    d["last_iov_was"] = py::make_tuple(p.lastBefore.firstRun, p.lastBefore.lastRun);
    d["last_iov_fate"] = p.lastIovFate();
    d["appended"] = p.appended.size();
    d["time"] = p.time.empty() ? py::object(py::none()) : py::object(py::str(p.time));
    return d;
  }

  // Two tags IOV by IOV, as conditions diff --json shows them.
  py::object diff(const std::string& a, const std::string& b) {
    return pythonOf(conddb::tagDiffJson(unwrap(conddb::diffTags(*db_, a, b))));
  }

  // A tag as the CSV text conditions export writes (pandas.read_csv(io.StringIO(text), comment="#")).
  std::string exportCsv(const std::string& tag) { return unwrap(conddb::tagCsv(*db_, tag)); }

 private:
  std::unique_ptr<conddb::Database> db_;
};

}  // namespace

void bindConditions(py::module_& m) {
  py::class_<Conditions>(m, "Conditions",
                         "A conditions database (sqlite:PATH, a path, or postgresql://user@host:port/db): "
                         "calibrations stored by run range in tags")
      .def(py::init<const std::variant<std::string, Path>&, bool>(), py::arg("uri"), py::arg("create") = false,
           "opens the database; create=True makes a new SQLite file (or a PostgreSQL schema), as conditions init")
      .def_property_readonly("uri", &Conditions::uri)
      .def(
          "tags", [](Conditions& c) { return c.tags(""); },
          "every tag as conditions list --json shows it: {tag, state, description, created, iovs: [...]}")
      .def(
          "tag",
          [](Conditions& c, const std::string& name) {
            if (name.empty()) raise(Error{"tag: a tag's name (tags() lists them all)"});
            return c.tags(name);
          },
          py::arg("name"), "one tag as conditions list --tag NAME --json shows it")
      .def("get", &Conditions::get, py::arg("tag"), py::arg("run"), py::arg("detector") = py::none(),
           "the calibration valid for a run: {parameters (12, native units), first_run, last_run, payload, "
           "inserted, file (the parameter file's text, as conditions get -o writes it)}")
      .def("put", &Conditions::put, py::arg("tag"), py::arg("runs"), py::arg("path"), py::arg("description") = "",
           py::arg("detector") = py::none(),
           "stores a fit result or parameter file for runs (first, last) or one run (the tag is created if new): "
           "{payload, new_tag, warnings}")
      .def("lock", &Conditions::lock, py::arg("tag"), "publishes a tag (state 'published'): its IOVs never change")
      .def("retire", &Conditions::retire, py::arg("tag"), py::arg("reason") = "",
           "makes a tag made by mistake invalid: kept and listed with its reason, never served again "
           "(a published tag never is)")
      .def("state", &Conditions::state, py::arg("tag"), py::arg("to") = py::none(), py::arg("reason") = "",
           "a tag's state; with to=STATE, the transition first (conditions state --set): open, testing, "
           "validated, published, running, invalid")
      .def("history", &Conditions::history, py::arg("tag"),
           "every change of a tag, oldest first, as conditions history --json: [{time, change, user, host, ...}]")
      .def("promote", &Conditions::promote, py::arg("source"), py::arg("to"), py::arg("first_safe_run"),
           py::arg("dry_run") = false,
           "appends a validated tag's IOVs to a running one from the first safe run (conditions promote)")
      .def("diff", &Conditions::diff, py::arg("a"), py::arg("b"),
           "two tags IOV by IOV, as conditions diff --json: {tag_a, tag_b, pairs: [{first_run, last_run, "
           "parameters: {name: {a, error_a, b, error_b, difference, z, unit}}, ...}], only_a, only_b}")
      .def("export", &Conditions::exportCsv, py::arg("tag"),
           "a tag as CSV text, one row per IOV, as conditions export writes it");
}

}  // namespace emcalign::python
