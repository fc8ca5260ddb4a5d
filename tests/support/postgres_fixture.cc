// The ctest fixture around the tests that use PostgreSQL: one
// server for the whole ctest run, in DIR.
//
//   fesbench_test_postgres_fixture start DIR   starts it, writes DIR/url
//   fesbench_test_postgres_fixture stop DIR    stops it, removes DIR
//
// Without the server binaries `start` says so and writes no url: the tests
// then skip with that message.

#include <cstring>
#include <fstream>
#include <iostream>

#include "tests/support/postgres_server.h"

int main(int argc, char** argv) {
  using fesbench::testing::PostgresServer;
  if (argc != 3 || (std::strcmp(argv[1], "start") != 0 && std::strcmp(argv[1], "stop") != 0)) {
    std::cerr << "usage: " << argv[0] << " start|stop DIR\n";
    return 2;
  }
  const std::filesystem::path dir = argv[2];
  if (std::strcmp(argv[1], "stop") == 0) {
    PostgresServer::StopIn(dir);
    return 0;
  }
  PostgresServer::StopIn(dir);  // a server a killed run left behind
  if (PostgresServer::BinDir().empty()) {
    std::cout << fesbench::testing::kBinariesMissing << ": the PostgreSQL tests will skip\n";
    return 0;
  }
  auto server = PostgresServer::Start(dir);
  if (!server.ok()) {
    std::cerr << server.status().ToString() << "\n";
    return 1;
  }
  (*server)->Detach();
  std::ofstream(dir / "url") << (*server)->Url("") << "\n";
  std::cout << "PostgreSQL for the tests at " << (*server)->Url("") << "\n";
  return 0;
}
