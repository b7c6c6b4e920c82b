// Writes the sample run of sample_run.hpp to the path given as the only argument.
#include <cstdio>

#include "sample_run.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: write_sample_run FILE.h5\n");
    return 2;
  }
  writeSampleRun(argv[1]);
  return 0;
}
