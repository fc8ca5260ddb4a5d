// fesbench-model: the offline model command line (see cli.h). Wiring only.

#include <iostream>

#include "clients/model_cli/cli.h"

int main(int argc, char** argv) {
  return fesbench::cli::RunModelCli(argc, argv, std::cout, std::cerr);
}
