/* c_spring: the mass_spring reference participant written in C against the C API (cosim/cosim.h).
 * Run by cosim as: c_spring K X Y Z --couple ENDPOINT --name NAME --out DIR --quiet
 * Reads the force on its interface node, writes the displacement u = F/k (x only). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cosim/cosim.h"

int main(int argc, char** argv) {
  if (argc < 5) {
    fprintf(stderr, "usage: c_spring K X Y Z --couple ENDPOINT --name NAME [--out DIR]\n");
    return 2;
  }
  const double k = atof(argv[1]);
  const double node[3] = {atof(argv[2]), atof(argv[3]), atof(argv[4])};
  const char *endpoint = NULL, *name = NULL;
  for (int i = 5; i + 1 < argc; ++i) {
    if (strcmp(argv[i], "--couple") == 0) endpoint = argv[i + 1];
    if (strcmp(argv[i], "--name") == 0) name = argv[i + 1];
  }
  cosim_participant* p = cosim_create(name, endpoint, 60.0);
  if (!p || cosim_add_mesh(p, "interface", node, 1, NULL, 0) || cosim_add_read(p, "interface", "force", 3) ||
      cosim_add_write(p, "interface", "displacement", 3) || cosim_initialize(p, NULL, NULL)) {
    fprintf(stderr, "c_spring: %s\n", cosim_last_error(p));
    return 4;
  }
  cosim_window w;
  int status;
  while ((status = cosim_next_window(p, &w)) == 1) {
    double f[3], u[3] = {0, 0, 0};
    if (cosim_read(p, "interface", "force", f, 3)) break;
    u[0] = f[0] / k;
    if (cosim_write(p, "interface", "displacement", u, 3) || cosim_complete(p, 0.0, 0.0)) break;
  }
  if (status < 0 || status == 1) {
    fprintf(stderr, "c_spring: %s\n", cosim_last_error(p));
    cosim_destroy(p);
    return 4;
  }
  cosim_destroy(p);
  return 0;
}
