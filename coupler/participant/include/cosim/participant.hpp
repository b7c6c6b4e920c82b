#pragma once
// The participant side of the coupling protocol: what a solver (or any external code) links to join a
// coupled run. Call order:
//   Participant p(name, endpoint);
//   p.addMesh(…); p.addRead(mesh, field, components); p.addWrite(…);
//   p.initialize();                                   // HELLO → WELCOME
//   while (p.nextWindow(w)) {                         // ADVANCE, or false on FINALIZE
//     if (w.restoreCheckpoint) restore(); if (w.saveCheckpoint) save();
//     auto in = p.read(mesh, field);                  // inputs of this iteration
//     … advance the solver from w.time by w.dt …
//     p.write(mesh, field, out);                      // every declared write
//     p.complete(solverSeconds, stableDt);            // RESULT
//   }
// A background thread sends heartbeats while the solver computes, so the coupler can tell a busy
// participant from a stopped one. If the coupler goes away (its process ends, or it stays silent for
// `timeout`), the waiting call throws. Errors: cosim::CouplingError (the run cannot go on). Not thread
// safe.

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "cosim/coupled_solver.hpp"

namespace cosim {

class CouplingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The protocol calls the window loop (cosim/window_loop.hpp) makes: Participant's, or a scripted
/// coupler's in a test.
class CouplingChannel {
 public:
  virtual ~CouplingChannel() = default;
  virtual void addMesh(const std::string& mesh, std::span<const double> nodes, std::span<const std::uint32_t> triangles) = 0;
  virtual void addCells(const std::string& mesh, int nodesPerCell, std::span<const std::uint32_t> cells) = 0;
  virtual void addRead(const std::string& mesh, const std::string& field, int components) = 0;
  virtual void addWrite(const std::string& mesh, const std::string& field, int components) = 0;
  virtual void offerCheckpoints() = 0;
  virtual void initialize() = 0;
  virtual bool nextWindow(Window& w) = 0;
  virtual std::span<const double> read(const std::string& mesh, const std::string& field) const = 0;
  virtual void write(const std::string& mesh, const std::string& field, std::span<const double> data) = 0;
  virtual void complete(double solverSeconds, double stableDt) = 0;
  virtual void fail(const std::string& text, bool instability = false) = 0;
  /// Retries (protocol feature kRetries): offered before initialize(); retries() says whether the coupler
  /// agreed. diverged() then answers the iteration with a RESULT flagged kDiverged instead of an ERROR.
  virtual void offerRetries() {}
  virtual bool retries() const { return false; }
  virtual void diverged(const std::string& text) { fail(text, true); }
};

class Participant : public CouplingChannel {
 public:
  /// `timeout`: how long the coupler may stay silent (it sends heartbeats about once a second while it
  /// waits) before this participant decides it is gone. `token`: the run's credential for this
  /// participant; empty: the environment's COSIM_TOKEN, else the first line of the file COSIM_TOKEN_FILE.
  Participant(std::string name, std::string endpoint, std::chrono::milliseconds timeout = std::chrono::seconds(60),
              std::string token = {});
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  /// An interface mesh: node coordinates (x, y, z per node) and triangles (may be empty).
  void addMesh(const std::string& mesh, std::span<const double> nodes, std::span<const std::uint32_t> triangles) override;
  /// Tetrahedra (4 nodes per cell) or segments (2) of a mesh added before: a volume or a line the coupler
  /// interpolates in (the barycentric mapping).
  void addCells(const std::string& mesh, int nodesPerCell, std::span<const std::uint32_t> cells) override;
  void addRead(const std::string& mesh, const std::string& field, int components) override;
  void addWrite(const std::string& mesh, const std::string& field, int components) override;

  /// Before initialize(): this participant can write on-disk checkpoints (Window::checkpoint).
  void offerCheckpoints() override;
  /// HELLO → WELCOME. Returns the coupling window and end time from the coupler.
  void initialize() override;
  double windowSize() const { return windowSize_; }
  double endTime() const { return endTime_; }

  /// Waits for the next instruction: true with `w` filled (ADVANCE), false when the run ends (FINALIZE,
  /// acknowledged with BYE).
  bool nextWindow(Window& w) override;
  std::span<const double> read(const std::string& mesh, const std::string& field) const override;
  void write(const std::string& mesh, const std::string& field, std::span<const double> data) override;
  /// RESULT with every declared write.
  void complete(double solverSeconds, double stableDt) override;
  /// ERROR to the coupler (e.g. the solver failed); the coupler stops the run. `instability`: the
  /// solver diverged (flag kErrorInstability; the coupler's exit code is then 3, not 4).
  void fail(const std::string& text, bool instability = false) override;
  void offerRetries() override;
  bool retries() const override;
  /// RESULT flagged kDiverged with the reason: the solver diverged in this iteration; the next ADVANCE
  /// restores the window's start (or the coupler ends the run).
  void diverged(const std::string& text) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double windowSize_ = 0.0, endTime_ = 0.0;
};

}  // namespace cosim
