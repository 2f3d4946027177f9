// friction-identify: placeholder entry point while the CLI is assembled.
#include <iostream>
int main() {
  std::cerr << "friction-identify: not yet assembled\n";
  return 2;
}
