#include "emcalign/conddb/address.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/core/secrets.hpp"

namespace emcalign::conddb {

namespace {

constexpr std::string_view kSqlite = "sqlite:";
constexpr std::string_view kPostgresSchemes[] = {"postgresql://", "postgres://"};
constexpr std::string_view kPasswordHint =
    "give the password through libpq's PGPASSFILE (~/.pgpass) or PGPASSWORD, not in the URI";
constexpr int kConnectTimeoutSeconds = 20;
// A password shorter than this is not searched for in libpq's messages (it would blank out
// letters of every word); the URI and its user:password part are, whatever their length.
constexpr std::size_t kMinSecretToSearch = 4;

std::string_view postgresScheme(std::string_view uri) {
  for (std::string_view s : kPostgresSchemes) {
    if (uri.starts_with(s)) return s;
  }
  return {};
}

// libpq's connection parameters whose values are not secrets: shown as given. Any other
// parameter's value is not shown (a misspelled "passwd", "pwd", "pass" would be a password).
bool isHarmless(std::string_view key) {
  static constexpr std::string_view kShown[] = {"host",
                                                "hostaddr",
                                                "port",
                                                "dbname",
                                                "user",
                                                "connect_timeout",
                                                "client_encoding",
                                                "options",
                                                "application_name",
                                                "fallback_application_name",
                                                "keepalives",
                                                "keepalives_idle",
                                                "keepalives_interval",
                                                "keepalives_count",
                                                "tcp_user_timeout",
                                                "replication",
                                                "gssencmode",
                                                "sslmode",
                                                "requiressl",
                                                "sslcompression",
                                                "sslcert",
                                                "sslkey",
                                                "sslrootcert",
                                                "sslcrl",
                                                "sslcrldir",
                                                "sslsni",
                                                "requirepeer",
                                                "ssl_min_protocol_version",
                                                "ssl_max_protocol_version",
                                                "krbsrvname",
                                                "gsslib",
                                                "service",
                                                "target_session_attrs",
                                                "load_balance_hosts",
                                                "channel_binding",
                                                "passfile"};
  return std::find(std::begin(kShown), std::end(kShown), key) != std::end(kShown);
}

using core::percentDecoded;

std::vector<std::string_view> split(std::string_view s, char by) {
  std::vector<std::string_view> out;
  std::size_t from = 0;
  while (true) {
    const auto at = s.find(by, from);
    out.push_back(s.substr(from, at == std::string_view::npos ? std::string_view::npos : at - from));
    if (at == std::string_view::npos) return out;
    from = at + 1;
  }
}

// "name:" at the start, as a URI scheme is written (letters, then letters, digits, + - .).
std::string_view schemeOf(std::string_view uri) {
  if (uri.empty() || !std::isalpha(static_cast<unsigned char>(uri[0]))) return {};
  for (std::size_t i = 1; i < uri.size(); ++i) {
    const char c = uri[i];
    if (c == ':') return uri.substr(0, i);
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '+' && c != '-' && c != '.') return {};
  }
  return {};
}

Result<DatabaseAddress> sqliteAddress(std::string path, std::string_view uri) {
  DatabaseAddress a;
  a.kind = DatabaseAddress::Kind::Sqlite;
  if (path.empty()) return Error{fmt::format("'{}': no file in this database address (sqlite:PATH)", uri)};
  if (path.starts_with(":memory") || path == ":") {
    return Error{
        fmt::format("'{}': an in-memory SQLite database vanishes when the command ends, with everything stored in it: "
                    "give a file (sqlite:PATH)",
                    uri)};
  }
  if (path.starts_with("file:")) {
    return Error{fmt::format(
        "'{}': SQLite URI filenames (file:..., with options such as mode=memory or vfs=unix-none) are not "
        "taken: a memory database or one without locking loses what a campaign stores; give the file's path",
        uri)};
  }
  // SQLite takes NAME-wal, NAME-shm and NAME-journal for the journals of NAME: a database so named
  // is deleted as a stale journal the moment NAME is opened.
  for (const std::string_view suffix : {"-wal", "-shm", "-journal"}) {
    if (path.size() > suffix.size() && path.ends_with(suffix)) {
      const std::string_view base = std::string_view(path).substr(0, path.size() - suffix.size());
      return Error{fmt::format(
          "'{}': the name of a journal SQLite keeps beside {}: it would delete this database as a stale journal "
          "when {} is opened; give it another name",
          uri, base, base)};
    }
  }
  a.file = std::move(path);
  a.shown = std::string(kSqlite) + a.file;
  return a;
}

}  // namespace

struct AddressParser {
  static Result<DatabaseAddress> postgres(std::string_view uri, std::string_view scheme);
};

Result<DatabaseAddress> AddressParser::postgres(std::string_view uri, std::string_view scheme) {
  DatabaseAddress a;
  a.kind = DatabaseAddress::Kind::Postgres;
  const std::string_view rest = uri.substr(scheme.size());
  // libpq reads user[:password]@ up to the first '@' or '/'.
  const auto end = rest.find_first_of("@/");
  std::string_view userinfo, after = rest;
  if (end != std::string_view::npos && rest[end] == '@') {
    userinfo = rest.substr(0, end);
    after = rest.substr(end + 1);
  }
  if (after.find('@') != std::string_view::npos) {
    return Error{fmt::format(
        "{}…: a '@' or '/' in the user name or password of a URI must be percent-encoded (%40, %2F), or libpq "
        "reads part of the password as the host or the port; better, {}",
        scheme, kPasswordHint)};
  }
  const auto colon = userinfo.find(':');
  const std::string_view user = userinfo.substr(0, colon);
  std::vector<std::string> secrets;
  auto addSecret = [&](std::string_view raw) {
    if (raw.empty()) return;
    secrets.emplace_back(raw);
    if (std::string decoded = percentDecoded(raw); decoded != raw) secrets.push_back(std::move(decoded));
  };
  if (colon != std::string_view::npos) addSecret(userinfo.substr(colon + 1));
  const auto question = after.find('?');
  const std::string_view location = after.substr(0, question);
  std::string shownQuery;
  if (question != std::string_view::npos) {
    for (std::string_view param : split(after.substr(question + 1), '&')) {
      const auto eq = param.find('=');
      std::string key = percentDecoded(param.substr(0, eq));
      std::transform(key.begin(), key.end(), key.begin(), [](unsigned char c) { return std::tolower(c); });
      // password, and sslpassword (the passphrase of the client's key); a parameter whose
      // name is not separated from its value ("password%3Dsecret") is one secret as a whole.
      if (key.find("password") != std::string::npos || eq == std::string_view::npos) {
        addSecret(eq != std::string_view::npos ? param.substr(eq + 1) : param);
        continue;
      }
      if (!shownQuery.empty()) shownQuery += '&';
      if (isHarmless(key)) {
        shownQuery.append(param);
      } else {  // a misspelled password ("passwd", "pwd") is shown as such, not with its value
        addSecret(param.substr(eq + 1));
        shownQuery += std::string(param.substr(0, eq)) + "=…";
      }
    }
  }
  a.shown = fmt::format("{}{}{}{}{}{}", scheme, user, user.empty() ? "" : "@", location, shownQuery.empty() ? "" : "?",
                        shownQuery);
  a.connection = std::string(uri);
  if (a.connection.find("connect_timeout=") == std::string::npos) {
    // A server that does not answer is an error after a while, not a hang.
    a.connection += question == std::string_view::npos ? "?" : "&";
    a.connection += fmt::format("connect_timeout={}", kConnectTimeoutSeconds);
  }
  if (!secrets.empty() && !userinfo.empty()) secrets.emplace_back(userinfo);
  a.secrets_ = std::move(secrets);
  a.raw_ = std::string(uri);
  return a;
}

Result<DatabaseAddress> DatabaseAddress::parse(std::string_view uri) {
  if (uri.empty()) return Error{"an empty database address (sqlite:PATH, a path, or postgresql://…)"};
  if (uri.find('\0') != std::string_view::npos) {
    return Error{"a database address with a NUL character (it would be cut there): not taken"};
  }
  if (const std::string_view scheme = postgresScheme(uri); !scheme.empty()) return AddressParser::postgres(uri, scheme);
  if (uri.starts_with(kSqlite)) {
    std::string path(uri.substr(kSqlite.size()));
    if (path.starts_with("//")) path = path.substr(2);  // sqlite://PATH, sqlite:///absolute
    return sqliteAddress(std::move(path), uri);
  }
  if (const std::string_view scheme = schemeOf(uri); !scheme.empty()) {
    return Error{fmt::format(
        "'{}:…': unknown database scheme '{}' (sqlite:PATH, a path, or postgresql://user@host:port/db){}", scheme,
        scheme, scheme.starts_with("postgres") ? "; a PostgreSQL URI starts with postgresql://" : "")};
  }
  if (uri.find('=') != std::string_view::npos) {
    return Error{fmt::format(
        "the database address looks like a libpq keyword string (key=value ...; not shown, it may hold a "
        "password), which emcalign does not take: write postgresql://user@host:port/db, and {} (for an SQLite "
        "file whose name holds '=': sqlite:PATH)",
        kPasswordHint)};
  }
  return sqliteAddress(std::string(uri), uri);
}

std::string DatabaseAddress::redact(std::string message) const {
  auto replaceAll = [&](const std::string& what, const std::string& by) {
    if (what.empty()) return;
    for (auto at = message.find(what); at != std::string::npos; at = message.find(what, at + by.size())) {
      message.replace(at, what.size(), by);
    }
  };
  // The URI as given and as libpq got it first, then user:password, then the password as
  // written and decoded (longest first, so that a part never hides a longer form).
  replaceAll(connection, shown);
  replaceAll(raw_, shown);
  std::vector<std::string> order = secrets_;
  std::sort(order.begin(), order.end(), [](const auto& x, const auto& y) { return x.size() > y.size(); });
  for (const std::string& s : order) {
    if (s.size() >= kMinSecretToSearch || s.find(':') != std::string::npos) replaceAll(s, "***");
  }
  return message;
}

std::vector<std::string> DatabaseAddress::files() const {
  if (kind != Kind::Sqlite) return {};
  std::vector<std::string> out = {file, file + "-wal", file + "-shm", file + "-journal"};
  // Given through a link, SQLite keeps its journals beside the file the link points to.
  std::error_code ec;
  const auto real = std::filesystem::canonical(file, ec);
  if (!ec && real != std::filesystem::absolute(file, ec).lexically_normal()) {
    for (const char* suffix : {"", "-wal", "-shm", "-journal"}) out.push_back(real.string() + suffix);
  }
  return out;
}

std::string shownAddress(std::string_view uri) {
  if (auto a = DatabaseAddress::parse(uri); a) return a->shown;
  if (const std::string_view scheme = postgresScheme(uri); !scheme.empty()) return std::string(scheme) + "…";
  if (!uri.starts_with(kSqlite) && (uri.find('=') != std::string_view::npos || !schemeOf(uri).empty())) {
    return "(a database address, not shown)";
  }
  return std::string(uri);
}

}  // namespace emcalign::conddb
