#pragma once
// The test suite's own PostgreSQL server (tests/postgres/pg_server.py). Under ctest the
// fixture `postgres` starts one for the whole run and names its state file in
// EMCALIGN_TEST_POSTGRES_STATE; a test binary run by hand starts its own and stops it at exit.
// Each test then takes a fresh database on that server.

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

#include <unistd.h>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <pqxx/pqxx>

namespace emcalign::testing {

namespace detail {
inline std::string& ownStateFile() {
  static std::string path;
  return path;
}
inline void stopOwnServer() {
  if (ownStateFile().empty()) return;
  const std::string cmd =
      fmt::format("/usr/bin/python3 {}/tests/postgres/pg_server.py stop {}", EMCALIGN_SOURCE_DIR, ownStateFile());
  [[maybe_unused]] int rc = std::system(cmd.c_str());
}
}  // namespace detail

/// The URI of the server's `postgres` database (its administrator's), starting the server if
/// this process has none.
inline std::string postgresServerUri() {
  static const std::string uri = [] {
    std::string state;
    if (const char* env = std::getenv("EMCALIGN_TEST_POSTGRES_STATE"); env != nullptr && *env != '\0') {
      state = env;
    } else {
      state = fmt::format("/tmp/emcalign-test-pg-{}.json", ::getpid());
      const std::string cmd = fmt::format("/usr/bin/python3 {}/tests/postgres/pg_server.py start {} >/dev/null",
                                          EMCALIGN_SOURCE_DIR, state);
      if (std::system(cmd.c_str()) != 0) throw std::runtime_error("cannot start the test PostgreSQL server");
      detail::ownStateFile() = state;
      std::atexit(detail::stopOwnServer);
    }
    std::ifstream in(state);
    if (!in) throw std::runtime_error("no PostgreSQL test server state file " + state);
    std::stringstream text;
    text << in.rdbuf();
    return nlohmann::json::parse(text.str()).at("uri").get<std::string>();
  }();
  return uri;
}

/// A new, empty database on the test server; returns its URI.
inline std::string freshPostgresDatabase() {
  static std::atomic<int> counter{0};
  const std::string server = postgresServerUri();
  const std::string name = fmt::format("t_{}_{}", ::getpid(), counter++);
  pqxx::connection c(server);
  pqxx::nontransaction tx(c);
  tx.exec("DROP DATABASE IF EXISTS " + name);
  tx.exec("CREATE DATABASE " + name);
  return server.substr(0, server.rfind('/') + 1) + name;
}

}  // namespace emcalign::testing
