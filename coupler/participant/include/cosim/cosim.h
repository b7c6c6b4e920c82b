/* The C API of libcosim: the participant side of the coupling protocol for C and Fortran codes
 * (Fortran: bind with iso_c_binding). Mirrors cosim/participant.hpp; call order:
 *   cosim_create → cosim_add_mesh / cosim_add_read / cosim_add_write → cosim_initialize →
 *   while (cosim_next_window(p, &w) == 1) { cosim_read …; solve; cosim_write …; cosim_complete } →
 *   cosim_destroy.
 * Every function returning int gives 0 (or 1 for "a window") on success and -1 on failure; the message
 * is then in cosim_last_error(p). Arrays are float64, 3 values per node for vector fields. */
#ifndef COSIM_H
#define COSIM_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct cosim_participant cosim_participant;

typedef struct {
  uint64_t index;     /* coupling window index */
  uint32_t iteration; /* iteration within the window */
  double time;        /* window start [s] */
  double dt;          /* window length [s] */
  int save_checkpoint, restore_checkpoint, write_output;
} cosim_window;

/* Connects to the coupler at `endpoint` as `name`; NULL on failure. timeout_s: how long the coupler may
 * stay silent before it counts as gone (0: 60 s). The token is read from COSIM_TOKEN or the file named
 * by COSIM_TOKEN_FILE (the coupler sets the first for participants it launches). */
cosim_participant* cosim_create(const char* name, const char* endpoint, double timeout_s);
void cosim_destroy(cosim_participant* p);
const char* cosim_last_error(const cosim_participant* p);

int cosim_add_mesh(cosim_participant* p, const char* mesh, const double* nodes, size_t node_count,
                   const uint32_t* triangles, size_t triangle_count);
int cosim_add_read(cosim_participant* p, const char* mesh, const char* field, int components);
int cosim_add_write(cosim_participant* p, const char* mesh, const char* field, int components);
/* HELLO → WELCOME; window and end time from the coupler (either pointer may be NULL). */
int cosim_initialize(cosim_participant* p, double* window, double* end_time);
/* 1: a window to compute (w filled), 0: the run ended (FINALIZE answered), -1: error. */
int cosim_next_window(cosim_participant* p, cosim_window* w);
/* Copies the input field into out[0 .. count); fails if the sizes differ. */
int cosim_read(cosim_participant* p, const char* mesh, const char* field, double* out, size_t count);
int cosim_write(cosim_participant* p, const char* mesh, const char* field, const double* data, size_t count);
int cosim_complete(cosim_participant* p, double solver_seconds, double stable_dt);
/* Tells the coupler this participant failed (the run stops). */
void cosim_fail(cosim_participant* p, const char* text);

#ifdef __cplusplus
}
#endif

#endif /* COSIM_H */
