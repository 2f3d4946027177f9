// friction-identify: identifies friction models from displacement-force records.
// The commands are in src/cli/; see cli.md for the contract.
#include "cli.hpp"

int main(int argc, char** argv) {
  return friction::cli::run(argc, argv);
}
