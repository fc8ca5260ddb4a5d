// fesbench: the analyst command line (see cli.h). Wiring only.

#include <unistd.h>

#include <iostream>

#include "clients/cli/cli.h"

int main(int argc, char** argv) {
  return fesbench::cli::RunFesbenchCli(argc, argv, std::cout, std::cerr,
                                       ::isatty(STDOUT_FILENO) == 1);
}
