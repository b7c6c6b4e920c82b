// The bridging domain (volume coupling; Xiao & Belytschko 2004, Kozicki & Donzé 2008 §2.3, eqs. (10)–(13);
// docs/validation/bridging.md). A continuum participant (its mesh `bridge` has cells: the elements of
// the overlap) and a particle participant (its `bridge` mesh is the particles in the overlap) share a
// zone in which each carries its energy weighted, α for the continuum and β = 1 − α for the particles.
// A window is one common time step, in two iterations:
//   1. both take a trial step with the multiplier forces at zero and write the overlap's velocities
//      (continuum v_I, particles u_J) and weighted masses (α_I M_I, β_J m_J);
//   2. the scheme solves for the multipliers λ_J that make every particle move with the continuum at
//      its place, N(X_J) v = u_J, and both repeat the step from its start with the multiplier forces
//      held over it: +λ_J on particle J, −Σ_J N_I(X_J) λ_J on node I.
// With N the barycentric interpolation (n_particles × n_nodes) and Δt the step's kick (half the step in
// the first, which leapfrog starts from the velocities at t = 0), the constraint after the corrected step,
// N (v* − Δt (αM)⁻¹ Nᵀ λ) = u* + Δt (βm)⁻¹ λ, is the linear system
//   A λ = (N v* − u*) / Δt,   A = N (αM)⁻¹ Nᵀ + (βm)⁻¹,
// symmetric positive definite, n_particles × n_particles, the same for the three directions, and sparse
// (particles interact through the nodes of the cells that hold them). It is solved through the nodes'
// system B = αM + Nᵀ (βm) N (Woodbury's identity, multipliers()), factored once (sparse LDLᵀ) and again
// only when a weighted mass changes. `coupling.constraint: tie` instead sets each particle to N v* and
// leaves the continuum alone, the plain tie the multipliers improve on: λ = βm (N v* − u*) / Δt on the
// particles, nothing on the nodes. Rotations are not constrained: the particles'
// spin is their own (the paper's eq. (12) ties it too; a bar or a slab loaded in its plane does not
// need it).
#include <algorithm>
#include <chrono>
#include <cmath>

#include <Eigen/SparseCholesky>
#include <fmt/format.h>

#include "cosim/protocol.hpp"
#include "common/config.hpp"
#include "common/errors.hpp"
#include "common/state_archive.hpp"
#include "common/summary.hpp"
#include "schemes.hpp"

namespace cosim {

const std::vector<std::string> kBridgeMeshes = {"bridge", "bridge_energy"};

namespace {

namespace pr = protocol;
using Sparse = Eigen::SparseMatrix<double>;
using Rows = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

bool hasCells(const InterfaceMesh& m) { return !m.tetrahedra.empty() || !m.triangles.empty() || !m.segments.empty(); }

class Bridging final : public Scheme {
 public:
  Bridging(const CouplingSpec& spec, const SchemeHost& host, bool tie)
      : endTime_(spec.endTime), tie_(tie), energyTolerance_(spec.energyTolerance) {
    std::vector<std::size_t> continuum, particles, others;
    for (std::size_t p = 0; p < host.participants(); ++p) {
      const auto& meshes = host.meshes(p);
      const auto it = meshes.find("bridge");
      if (it == meshes.end()) others.push_back(p);
      else (hasCells(it->second) ? continuum : particles).push_back(p);
    }
    if (continuum.size() != 1 || particles.size() != 1 || !others.empty())
      throw common::ConfigError(fmt::format(
          "coupling.scheme: bridging couples two participants through their mesh `bridge`: one declares it with cells "
          "(the continuum's elements of the overlap) and one as points (the particles in it); this scene has {} with "
          "cells, {} of points and {} without a `bridge` mesh",
          continuum.size(), particles.size(), others.size()));
    fem_ = continuum.front(), dem_ = particles.front();
    const InterfaceMesh &from = host.meshes(fem_).at("bridge"), &to = host.meshes(dem_).at("bridge");
    if (to.nodes.empty())
      throw common::ConfigError(fmt::format("coupling.scheme: bridging: participant \"{}\" has no particle in the overlap "
                                            "(its mesh `bridge` has no nodes): its bridging zone and the continuum's "
                                            "do not meet",
                                            host.name(dem_)));
    try {
      map_ = makeMapping("barycentric", from, to);
    } catch (const std::invalid_argument& e) {
      throw common::ConfigError(fmt::format("coupling.scheme: bridging: the particles of \"{}\" must lie in the elements "
                                            "of \"{}\": {}",
                                            host.name(dem_), host.name(fem_), e.what()));
    }
  }

  WindowOutcome window(SchemeHost& host, std::uint32_t firstFlags) override {
    const std::size_t both[] = {fem_, dem_};
    auto& femForce = input(host, fem_, "bridge/force"), &demForce = input(host, dem_, "bridge/force");
    std::fill(femForce.begin(), femForce.end(), 0.0);
    std::fill(demForce.begin(), demForce.end(), 0.0);
    // The coupled system's energy, for a side whose own ledger is still at round-off.
    for (std::size_t p : both) {
      auto& in = host.inputs(p);
      if (const auto it = in.find("bridge_energy/scale"); it != in.end() && initialEnergy_ > 0) it->second.assign(1, initialEnergy_);
    }
    host.setIteration(0);
    for (std::size_t p : both) host.send(p, firstFlags | pr::kSaveCheckpoint);
    host.collect(both);
    if (host.window() == 0) checkStep(host);

    const double dt = host.windowSize();
    // Leapfrog from the velocities at t = 0: the first step's kick is half a step long, and so is the
    // velocity change a force held over it makes.
    const double kick = host.window() == 0 ? 0.5 * dt : dt;
    const auto t0 = std::chrono::steady_clock::now();
    factor(host);
    const Rows g = mismatch(host);
    // A tie moves each particle to the continuum's velocity at its place and leaves the continuum alone.
    const Rows lambda = (tie_ ? Rows(particleMass_.asDiagonal() * g) : multipliers(g)) / kick;
    Eigen::Map<Rows>(demForce.data(), lambda.rows(), 3) = lambda;
    Eigen::Map<Rows>(femForce.data(), static_cast<Eigen::Index>(map_->fromSize()), 3) =
        tie_ ? Rows(Rows::Zero(static_cast<Eigen::Index>(map_->fromSize()), 3)) : Rows(-(N_.transpose() * lambda));
    solveSeconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    host.setIteration(1);
    for (std::size_t p : both) host.send(p, pr::kRestoreCheckpoint);
    host.collect(both);
    const Rows after = mismatch(host);
    // The multipliers' power, λ · (u − N v), over the corrected velocities: zero when the constraint holds.
    multiplierWork_ += kick * -(lambda.cwiseProduct(after)).sum();
    const double scale = std::max({velocityScale(host, dem_), velocityScale(host, fem_), 1e-300});
    const double residual = after.rowwise().norm().maxCoeff();
    worstMismatch_ = std::max(worstMismatch_, residual / scale);
    largestMultiplier_ = std::max(largestMultiplier_, lambda.rowwise().norm().maxCoeff());
    energies(host);
    return {2, residual, residual / scale, true, true};
  }

  bool strong() const override { return true; }
  std::string describe() const override {
    return fmt::format("bridging scheme{}, {} particles on {} overlap nodes", tie_ ? " (a tie, no multipliers)" : "",
                       map_->toSize(), map_->fromSize());
  }

  void archive(common::StateArchive& a) override {
    a.io("multiplier_work", multiplierWork_), a.io("worst_mismatch", worstMismatch_);
    a.io("largest_multiplier", largestMultiplier_), a.io("initial_energy", initialEnergy_);
    a.io("energy_drift", energyDrift_), a.io("energy_continuum", energyFem_), a.io("energy_particles", energyDem_);
  }

  void report(common::Summary& s) const override {
    s.set("bridging_particles", static_cast<std::int64_t>(map_->toSize()));
    s.set("bridging_nodes", static_cast<std::int64_t>(map_->fromSize()));
    s.set("bridging_velocity_mismatch", worstMismatch_);
    s.set("bridging_largest_multiplier_n", largestMultiplier_);
    s.set("bridging_multiplier_work_j", multiplierWork_);
    s.set("bridging_solve_time_s", solveSeconds_);  // the multipliers: factor, mismatch, solve, forces
    s.set("bridging_factor_nonzeros", static_cast<std::int64_t>(solver_.matrixL().nestedExpression().nonZeros()));
    if (!(initialEnergy_ > 0)) return;
    // What of the energy at the start is on either side at the end: when a pulse starts in the continuum
    // and the run ends after it left the overlap, the continuum's share is what the overlap reflected.
    s.set("initial_energy_j", initialEnergy_);
    s.set("reflected_energy_fraction", energyFem_ / initialEnergy_);
    s.set("transmitted_energy_fraction", energyDem_ / initialEnergy_);
    s.set("energy_drift_fraction", energyDrift_);
    s.set("multiplier_work_fraction", multiplierWork_ / initialEnergy_);
  }

 private:
  static std::vector<double>& input(SchemeHost& host, std::size_t p, const std::string& field) {
    auto& in = host.inputs(p);
    const auto it = in.find(field);
    if (it == in.end())
      throw common::ConfigError(fmt::format("coupling.scheme: bridging: participant \"{}\" does not read {} (3 "
                                            "components: the multiplier force on each node of its overlap)",
                                            host.name(p), field));
    return it->second;
  }

  static const std::vector<double>& output(SchemeHost& host, std::size_t p, const std::string& field,
                                           std::size_t size) {
    auto& out = host.outputs(p);
    const auto it = out.find(field);
    if (it == out.end() || it->second.size() != size)
      throw common::ConfigError(fmt::format("coupling.scheme: bridging: participant \"{}\" must write {} ({} values, "
                                            "one {} per overlap node); it wrote {}",
                                            host.name(p), field, size, size == 0 ? "entry" : "set",
                                            it == out.end() ? std::string("none") : std::to_string(it->second.size())));
    return it->second;
  }

  // The window is the common step, which each participant takes in one step (its own dt does not split
  // it: substeps would leave all but the last unconstrained). Checked after the first trial step, which
  // one step beyond the stable limit cannot blow up.
  void checkStep(SchemeHost& host) const {
    const double dt = host.windowSize();
    std::size_t p = fem_;  // the participant of the smaller stable step
    for (std::size_t q : {fem_, dem_})
      if (host.stableStep(q) > 0 && (host.stableStep(p) <= 0 || host.stableStep(q) < host.stableStep(p))) p = q;
    const double stable = host.stableStep(p);
    if (!(stable > 0) || dt <= stable) return;
    const std::string fix = common::wholeStepValue(endTime_, 0.9 * stable);
    throw common::InstabilityError(
        {"bridging step above a stable step", fmt::format("participant {}", host.name(p)), 0.0,
         fmt::format("coupling.time_window = {:.4g} s is the common step; participant \"{}\" is stable up to {:.4g} s "
                     "(the smaller of the two)",
                     dt, host.name(p), stable),
         fmt::format("coupling.time_window = {} s (0.9 × that stable step, a whole number of steps of end_time)", fix),
         {"coupling.time_window=" + fix}});
  }

  // B = αM + Nᵀ (βm) N (multipliers()), factored again only when a weighted mass changed.
  void factor(SchemeHost& host) {
    const std::size_t nf = map_->fromSize(), nd = map_->toSize();
    const auto& mf = output(host, fem_, "bridge/mass", nf);
    const auto& md = output(host, dem_, "bridge/mass", nd);
    if (mf == massFem_ && md == massDem_) return;
    for (std::size_t p : {fem_, dem_})
      for (double m : p == fem_ ? mf : md)
        if (!(m > 0) || !std::isfinite(m))
          throw common::ConfigError(fmt::format("coupling.scheme: bridging: participant \"{}\" wrote a weighted mass "
                                                "{} in its overlap; every node needs a positive one (its bridging "
                                                "min_weight)",
                                                host.name(p), m));
    massFem_ = mf, massDem_ = md;
    checkWeights(host);
    N_ = Sparse(map_->matrix());
    particleMass_ = Eigen::Map<const Eigen::VectorXd>(md.data(), static_cast<Eigen::Index>(nd));
    Sparse B = N_.transpose() * particleMass_.asDiagonal() * N_;
    for (std::size_t i = 0; i < nf; ++i) B.coeffRef(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i)) += mf[i];
    solver_.compute(B);
    if (solver_.info() != Eigen::Success)
      throw common::ConfigError("coupling.scheme: bridging: the multiplier system could not be factored");
  }

  // α (the continuum's weight interpolated at each particle, clamped to [0, 1]: the continuum writes the
  // linear function unclamped, which its elements interpolate exactly) + β (the particle's) = 1: both
  // scenes describe the same zone.
  void checkWeights(SchemeHost& host) const {
    const std::size_t nf = map_->fromSize(), nd = map_->toSize();
    const auto& wf = output(host, fem_, "bridge/weight", nf);
    const auto& wd = output(host, dem_, "bridge/weight", nd);
    std::vector<double> alpha(nd);
    map_->consistent(wf, alpha, 1);
    for (std::size_t j = 0; j < nd; ++j)
      if (std::abs(std::clamp(alpha[j], 0.0, 1.0) + wd[j] - 1.0) > 1e-6) {
        const Vec3& x = host.meshes(dem_).at("bridge").nodes[j];
        throw common::ConfigError(fmt::format(
            "coupling.scheme: bridging: at particle {} ({:.6g}, {:.6g}, {:.6g}) the continuum's weight is {:.6g} and "
            "the particles' {:.6g}; they must sum to 1 (the same `bridging` zone in both participants' scenes)",
            j, x.x(), x.y(), x.z(), alpha[j], wd[j]));
      }
  }

  // A⁻¹ g by Woodbury's identity: with D = (βm)⁻¹ and W = (αM)⁻¹, (D + N W Nᵀ)⁻¹ = D⁻¹ − D⁻¹ N B⁻¹ Nᵀ D⁻¹,
  // B = W⁻¹ + Nᵀ D⁻¹ N = αM + Nᵀ (βm) N, the overlap's coupled mass matrix: a system of the nodes instead
  // of the particles, which outnumber them (docs/validation/bridging.md: its factor's non-zeros on the slab).
  Rows multipliers(const Rows& g) const {
    const Eigen::MatrixXd y = particleMass_.asDiagonal() * g;
    const Eigen::MatrixXd z = solver_.solve(Eigen::MatrixXd(N_.transpose() * y));
    return y - particleMass_.asDiagonal() * (N_ * z);
  }

  // N v − u per particle, from the last outputs.
  Rows mismatch(SchemeHost& host) const {
    const std::size_t nf = map_->fromSize(), nd = map_->toSize();
    const auto& vf = output(host, fem_, "bridge/velocity", 3 * nf);
    const auto& ud = output(host, dem_, "bridge/velocity", 3 * nd);
    Rows g(static_cast<Eigen::Index>(nd), 3);
    map_->consistent(vf, std::span<double>(g.data(), 3 * nd), 3);
    return g - Eigen::Map<const Rows>(ud.data(), static_cast<Eigen::Index>(nd), 3);
  }

  double velocityScale(SchemeHost& host, std::size_t p) const {
    double largest = 0.0;
    for (double v : host.outputs(p).at("bridge/velocity")) largest = std::max(largest, std::abs(v));
    return largest;
  }

  // Each side's mechanical energy (its weighted part in the overlap), if it writes bridge_energy/energy,
  // and the balance: mechanical energy, plus what each side dissipated less the work its other loads did,
  // is the initial energy; the multipliers' work cancels between the sides. A coupling that breaks it
  // (a tie, or a step too long) ends the run.
  void energies(SchemeHost& host) {
    const auto &of = host.outputs(fem_), &od = host.outputs(dem_);
    const auto f = of.find("bridge_energy/energy"), d = od.find("bridge_energy/energy");
    if (f == of.end() || d == od.end() || f->second.size() != 2 || d->second.size() != 2) return;
    energyFem_ = f->second[0], energyDem_ = d->second[0];
    const double balance = energyFem_ + energyDem_ + f->second[1] + d->second[1];
    if (initialEnergy_ < 0) initialEnergy_ = balance;
    if (!(initialEnergy_ > 0)) return;
    const double drift = std::abs(balance - initialEnergy_) / initialEnergy_;
    energyDrift_ = std::max(energyDrift_, drift);
    if (!(drift <= energyTolerance_)) {
      const std::string half = common::wholeStepValue(endTime_, 0.5 * host.windowSize());
      throw common::InstabilityError(
          {balance > initialEnergy_ ? "bridging energy growth" : "bridging energy loss", "the overlap",
           0.0,
           fmt::format("window {}: the coupled energy balance is off by {:.3g} of the initial energy {:.4g} J (allowed "
                       "{}, coupling.energy_tolerance){}",
                       host.window(), drift, initialEnergy_, energyTolerance_,
                       tie_ ? "; a tie does work on the particles that the continuum never returns" : ""),
           tie_ ? "coupling.constraint: multipliers (they do no work)"
                : fmt::format("coupling.time_window = {} s (half), or no dashpots in the overlap (a velocity-dependent "
                              "force makes the corrected step differ from the trial one)",
                              half),
           tie_ ? std::vector<std::string>{"coupling.constraint=multipliers"}
                : std::vector<std::string>{"coupling.time_window=" + half}});
    }
  }

  double endTime_;
  bool tie_ = false;
  double energyTolerance_;
  std::size_t fem_ = 0, dem_ = 0;
  std::unique_ptr<Mapping> map_;
  Sparse N_;
  Eigen::SimplicialLDLT<Sparse> solver_;  // of B (multipliers())
  Eigen::VectorXd particleMass_;
  std::vector<double> massFem_, massDem_;
  double solveSeconds_ = 0.0;
  double multiplierWork_ = 0.0, worstMismatch_ = 0.0, largestMultiplier_ = 0.0;
  double initialEnergy_ = -1.0, energyDrift_ = 0.0, energyFem_ = 0.0, energyDem_ = 0.0;
};

}  // namespace

SchemeKeys readBridging(const common::Config& c, CouplingSpec& spec) {
  // `tie` slaves the particles of the overlap to the continuum (no multipliers: the continuum feels
  // nothing), to show what the multipliers do.
  const bool tie = c.choice("constraint", {"multipliers", "tie"}, "multipliers") == "tie";
  refuseIterationKeys(c, spec);
  return {[tie](const CouplingSpec& s, const SchemeHost& host) { return std::make_unique<Bridging>(s, host, tie); }, {}};
}

}  // namespace cosim
