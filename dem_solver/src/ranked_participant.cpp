// RankedParticipant (ranked_participant.hpp): rank 0's window loop calls, sent to every rank and done there
// on each share.
#include "ranked_participant.hpp"

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <thread>

#include "common/errors.hpp"
#include "common/results_file.hpp"
#include "dem/coupled_dem.hpp"
#include "rank_messages.hpp"

namespace dem {

namespace {

std::uint32_t interfaceWall(const Scene& scene) {
  const auto& meshes = scene.sim->meshWalls().walls();
  for (std::uint32_t i = 0; i < meshes.size(); ++i)
    if (meshes[i].name == scene.interfaceWall) return i;
  throw std::logic_error("RankedParticipant: no interface wall (refuseWhatRanksCannotRun checks it)");
}

// Rank 0's order, on every rank. The other ranks wait here while rank 0 waits on the coupler, which may
// take as long as the other participants' windows: they sleep between tests rather than spin on a core
// those participants need.
void broadcastHead(double* head, int rank) {
  MPI_Request request;
  MPI_Ibcast(head, 3, MPI_DOUBLE, 0, MPI_COMM_WORLD, &request);
  if (rank == 0) {
    MPI_Wait(&request, MPI_STATUS_IGNORE);
    return;
  }
  using std::chrono::microseconds;
  const auto start = std::chrono::steady_clock::now();
  microseconds pause(20);
  for (int done = 0;;) {
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done) return;
    // The orders of one window follow each other within microseconds: spin for those.
    if (std::chrono::steady_clock::now() - start < microseconds(100)) continue;
    std::this_thread::sleep_for(pause);
    pause = std::min(2 * pause, microseconds(250));
  }
}

}  // namespace

RankedParticipant::RankedParticipant(Scene& scene, RankedSimulation& ranked, RankedOutput& output,
                                     StabilityMonitor& monitor, double criticalDt, int rank)
    : scene_(scene),
      sim_(*scene.sim),
      ranked_(ranked),
      output_(output),
      monitor_(monitor),
      rank_(rank),
      wall_(interfaceWall(scene)),
      reference_(sim_.meshWalls().walls()[wall_]),
      dt_(sim_.settings().dt),
      critical_(criticalDt),
      nextSnapshot_(scene.output.interval) {
  positions_.resize(reference_.nodes.size()), velocity_.resize(reference_.nodes.size());
}

void RankedParticipant::declare(cosim::InterfaceDeclaration& io) {
  CoupledDem::declareInterface(io, reference_);  // as one rank's: the coupler cannot tell them apart
}

void RankedParticipant::beginWindow(const cosim::Window&, const cosim::Substeps& sub, cosim::WindowIo& io) {
  order(kBeginWindow, sub.dt, io.rate("interface", "displacement"));
}

void RankedParticipant::step(const cosim::Window&, const cosim::Substep& s, cosim::WindowIo& io) {
  order(kStep, 0.0, io.read("interface", "displacement", s.begin));
  io.write("interface", "force", forces_);
}

void RankedParticipant::endWindow(const cosim::Window& w, cosim::WindowIo& io) {
  order(kEndWindow, w.time + w.dt, io.read("interface", "displacement", 1.0));
}

void RankedParticipant::order(Order what, double value, std::span<const double> data) {
  double head[3] = {static_cast<double>(what), value, static_cast<double>(data.size())};
  broadcastHead(head, rank_);
  if (!data.empty())
    MPI_Bcast(const_cast<double*>(data.data()), static_cast<int>(data.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  if (what != kFinish) apply(what, value, data);
}

bool RankedParticipant::stop(int code, const std::string& what) {
  if (applying_) return false;
  std::string text = what;
  double head[3] = {static_cast<double>(kStop), static_cast<double>(code), static_cast<double>(text.size())};
  broadcastHead(head, rank_);
  MPI_Bcast(text.data(), static_cast<int>(text.size()), MPI_CHAR, 0, MPI_COMM_WORLD);
  detail::alone = false;
  return true;
}

void RankedParticipant::follow() {
  std::vector<double> data;
  for (;;) {
    double head[3];
    broadcastHead(head, rank_);
    const auto what = static_cast<Order>(static_cast<int>(head[0]));
    const auto n = static_cast<std::size_t>(head[2]);
    if (what == kStop) {
      std::string text(n, '\0');
      MPI_Bcast(text.data(), static_cast<int>(n), MPI_CHAR, 0, MPI_COMM_WORLD);
      detail::alone = false;
      const int code = static_cast<int>(head[1]);
      text = "rank 0: " + text;
      if (code == static_cast<int>(common::ExitCode::kBadInput)) throw common::ConfigError(text);
      if (code == 1) throw std::runtime_error(text);
      throw common::SimulationError(text, static_cast<common::ExitCode>(code));
    }
    data.resize(n);
    if (n > 0) MPI_Bcast(data.data(), static_cast<int>(n), MPI_DOUBLE, 0, MPI_COMM_WORLD);
    if (what == kFinish) return;
    try {
      apply(what, head[1], data);
    } catch (const common::InstabilityError&) {
      // Every rank's, rank 0's too: it tells the coupler, which may repeat the window shorter.
    }
  }
}

void RankedParticipant::apply(Order what, double value, std::span<const double> data) {
  applying_ = true;
  detail::alone = true;
  try {
    switch (what) {
      case kBeginWindow:
        sim_.settings().dt = value;
        for (std::size_t i = 0; i < velocity_.size(); ++i)
          velocity_[i] = Vec3(data[3 * i], data[3 * i + 1], data[3 * i + 2]);
        break;
      case kStep: {
        placeWall(data);
        ranked_.step();
        const std::vector<Vec3>& nf = sim_.meshWalls().walls()[wall_].nodeForce;
        forces_.resize(3 * nf.size());
        static_assert(sizeof(Vec3) == 3 * sizeof(double));
        MPI_Reduce(nf.front().data(), forces_.data(), static_cast<int>(forces_.size()), MPI_DOUBLE, MPI_SUM, 0,
                   MPI_COMM_WORLD);
        break;
      }
      case kEndWindow:
        placeWall(data);
        sim_.settings().dt = dt_;
        pending_ = output_.sample();
        pending_.time = value;
        break;
      case kSave:
        saved_ = ranked_.save();
        break;
      case kRestore:
        if (saved_) ranked_.restore(*saved_);
        break;
      case kCommit:
        if (pending_.time < 0) break;
        if (common::snapshotDue(pending_.time, scene_.output.interval, nextSnapshot_))
          output_.writeParticles(pending_.time);  // the window's end, as one rank stamps it
        ++committed_;
        monitor_.check(sim_, ranked_.ledger(), ranked_.initialEnergy());  // the same ledger on every rank
        if (committed_ % 16 == 0) monitor_.observe(sim_);
        output_.write(pending_);
        if (committed_ % 64 == 0) output_.flush();
        pending_.time = -1.0;
        break;
      case kFinish:
      case kStop:
        break;
    }
  } catch (const common::InstabilityError&) {
    // A step's divergence and the summed ledger's verdict are every rank's.
    applying_ = false;
    detail::alone = false;
    throw;
  }
  applying_ = false;
}

void RankedParticipant::placeWall(std::span<const double> d) {
  for (std::size_t i = 0; i < positions_.size(); ++i)
    positions_[i] = reference_.nodes[i] + Vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
  sim_.meshWalls().setState(wall_, positions_, velocity_);
}

}  // namespace dem
