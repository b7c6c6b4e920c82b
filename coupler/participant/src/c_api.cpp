// The C API (cosim/cosim.h) over cosim::Participant: exceptions become -1 and a stored message.
#include <chrono>
#include <cstring>
#include <memory>
#include <string>

#include "cosim/cosim.h"
#include "cosim/participant.hpp"

struct cosim_participant {
  std::unique_ptr<cosim::Participant> impl;
  std::string error;
};

namespace {
template <class F>
int guard(cosim_participant* p, F&& f) {
  if (!p) return -1;
  try {
    return f();
  } catch (const std::exception& e) {
    p->error = e.what();
    return -1;
  }
}
}  // namespace

extern "C" {

cosim_participant* cosim_create(const char* name, const char* endpoint, double timeout_s) {
  try {
    auto* p = new cosim_participant;
    p->impl = std::make_unique<cosim::Participant>(
        name, endpoint, std::chrono::milliseconds(static_cast<long long>(timeout_s > 0 ? timeout_s * 1000 : 60000)));
    return p;
  } catch (...) {
    return nullptr;
  }
}

void cosim_destroy(cosim_participant* p) { delete p; }

const char* cosim_last_error(const cosim_participant* p) { return p ? p->error.c_str() : "no participant"; }

int cosim_add_mesh(cosim_participant* p, const char* mesh, const double* nodes, size_t nodeCount,
                   const uint32_t* triangles, size_t triangleCount) {
  return guard(p, [&] {
    p->impl->addMesh(mesh, std::span<const double>(nodes, 3 * nodeCount),
                     std::span<const std::uint32_t>(triangles, 3 * triangleCount));
    return 0;
  });
}

int cosim_add_read(cosim_participant* p, const char* mesh, const char* field, int components) {
  return guard(p, [&] {
    p->impl->addRead(mesh, field, components);
    return 0;
  });
}

int cosim_add_write(cosim_participant* p, const char* mesh, const char* field, int components) {
  return guard(p, [&] {
    p->impl->addWrite(mesh, field, components);
    return 0;
  });
}

int cosim_initialize(cosim_participant* p, double* window, double* endTime) {
  return guard(p, [&] {
    p->impl->initialize();
    if (window) *window = p->impl->windowSize();
    if (endTime) *endTime = p->impl->endTime();
    return 0;
  });
}

int cosim_next_window(cosim_participant* p, cosim_window* w) {
  return guard(p, [&] {
    cosim::Window win;
    if (!p->impl->nextWindow(win)) return 0;
    *w = cosim_window{win.index, win.iteration, win.time, win.dt, win.saveCheckpoint, win.restoreCheckpoint,
                      win.writeOutput};
    return 1;
  });
}

int cosim_read(cosim_participant* p, const char* mesh, const char* field, double* out, size_t count) {
  return guard(p, [&] {
    const auto data = p->impl->read(mesh, field);
    if (data.size() != count)
      throw cosim::CouplingError(std::string("cosim_read ") + mesh + "/" + field + ": " + std::to_string(data.size()) +
                                 " values arrived, the buffer holds " + std::to_string(count));
    std::memcpy(out, data.data(), count * sizeof(double));
    return 0;
  });
}

int cosim_write(cosim_participant* p, const char* mesh, const char* field, const double* data, size_t count) {
  return guard(p, [&] {
    p->impl->write(mesh, field, std::span<const double>(data, count));
    return 0;
  });
}

int cosim_complete(cosim_participant* p, double solverSeconds, double stableDt) {
  return guard(p, [&] {
    p->impl->complete(solverSeconds, stableDt);
    return 0;
  });
}

void cosim_fail(cosim_participant* p, const char* text) {
  if (p && p->impl) p->impl->fail(text);
}

}  // extern "C"
