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
// particles, nothing on the nodes.
// Rotations (eq. (12)'s λ_ω): where the continuum is of tetrahedra and the particles write their spin ω
// and weighted moments of inertia βI, each particle also spins with the continuum, ω_J = C_J v with
// C_J v = ½ ∇ × v at X_J (cosim::spinMatrix). The multipliers then are a force and a torque per particle,
// the operator G = [N ⊗ I₃; C] (6 n_particles × 3 n_nodes) and the masses [βm; βI], one right-hand side;
// the nodes' system B = αM ⊗ I₃ + Gᵀ [βm; βI] G couples the directions. `coupling.rotations: free`
// leaves the spin to the particles.
#include <algorithm>
#include <chrono>
#include <cmath>

#include <Eigen/SparseCholesky>
#include <fmt/format.h>

#include "cosim/protocol.hpp"
#include "common/bridging_zone.hpp"
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

enum class Rotations { kAuto, kConstrained, kFree };

bool hasCells(const InterfaceMesh& m) { return !m.tetrahedra.empty() || !m.triangles.empty() || !m.segments.empty(); }

class Bridging final : public Scheme {
 public:
  Bridging(const CouplingSpec& spec, const SchemeHost& host, bool tie, Rotations rotations)
      : endTime_(spec.endTime), tie_(tie), rotations_(rotations), energyTolerance_(spec.energyTolerance) {
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
    const auto t0 = std::chrono::steady_clock::now();
    try {
      map_ = makeMapping("barycentric", from, to);
    } catch (const std::invalid_argument& e) {
      throw common::ConfigError(fmt::format("coupling.scheme: bridging: the particles of \"{}\" must lie in the elements "
                                            "of \"{}\": {}",
                                            host.name(dem_), host.name(fem_), e.what()));
    }
    const bool tetrahedra = !from.tetrahedra.empty() && from.triangles.empty() && from.segments.empty();
    if (rotations_ == Rotations::kConstrained && !tetrahedra)
      throw common::ConfigError(fmt::format("coupling.rotations: constrained needs a continuum of tetrahedra in the "
                                            "overlap (the spin ½ ∇ × v of a truss or a membrane is not defined); "
                                            "\"{}\" declares {}",
                                            host.name(fem_), from.triangles.empty() ? "segments" : "triangles"));
    if (rotations_ != Rotations::kFree && tetrahedra) spinOperator_ = spinMatrix(from, to);
    setupSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  WindowOutcome window(SchemeHost& host, std::uint32_t firstFlags) override {
    const std::size_t both[] = {fem_, dem_};
    auto& femForce = input(host, fem_, "bridge/force"), &demForce = input(host, dem_, "bridge/force");
    std::fill(femForce.begin(), femForce.end(), 0.0);
    std::fill(demForce.begin(), demForce.end(), 0.0);
    if (const auto it = host.inputs(dem_).find("bridge/torque"); it != host.inputs(dem_).end())
      std::fill(it->second.begin(), it->second.end(), 0.0);
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
    if (!spinChosen_) chooseSpin(host);  // on the first window this process runs, a restarted one's too
    factor(host);
    const Eigen::MatrixXd g = mismatch(host);
    // A tie moves each particle to the continuum's velocity at its place and leaves the continuum alone.
    const Eigen::MatrixXd lambda = (tie_ ? Eigen::MatrixXd(rowMass_.asDiagonal() * g) : multipliers(g)) / kick;
    const auto nd = static_cast<Eigen::Index>(map_->toSize()), nf = static_cast<Eigen::Index>(map_->fromSize());
    if (spin_) {
      Eigen::Map<Eigen::VectorXd>(demForce.data(), 3 * nd) = lambda.topRows(3 * nd);
      auto& torque = input(host, dem_, "bridge/torque");
      Eigen::Map<Eigen::VectorXd>(torque.data(), 3 * nd) = lambda.bottomRows(3 * nd);
    } else {
      Eigen::Map<Rows>(demForce.data(), nd, 3) = lambda;
    }
    if (!tie_ && spin_) Eigen::Map<Eigen::VectorXd>(femForce.data(), 3 * nf) = -(G_.transpose() * lambda);
    else if (!tie_) Eigen::Map<Rows>(femForce.data(), nf, 3) = -(G_.transpose() * lambda);  // a tie: zero, as filled
    solveSeconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    host.setIteration(1);
    for (std::size_t p : both) host.send(p, pr::kRestoreCheckpoint);
    host.collect(both);
    const Eigen::MatrixXd after = mismatch(host);
    // The multipliers' power, λ · (u − N v) (and λ_ω · (ω − C v)), over the corrected velocities: zero
    // when the constraint holds.
    multiplierWork_ += kick * -(lambda.cwiseProduct(after)).sum();
    const Rows translation = spin_ ? Rows(Eigen::Map<const Rows>(after.data(), nd, 3)) : Rows(after);
    const double scale = std::max({largest(host, dem_, "bridge/velocity"), largest(host, fem_, "bridge/velocity"), 1e-300});
    const double residual = translation.rowwise().norm().maxCoeff();
    worstMismatch_ = std::max(worstMismatch_, residual / scale);
    if (spin_) {
      // Over the larger spin of the two sides, the particles' ω or the continuum's C v = ω + mismatch.
      const Eigen::Map<const Eigen::VectorXd> spin(after.data() + 3 * nd, 3 * nd);
      const auto& w = host.outputs(dem_).at("bridge/spin");
      const Eigen::Map<const Eigen::VectorXd> omega(w.data(), 3 * nd);
      const double spinScale = std::max({omega.lpNorm<Eigen::Infinity>(), (omega + spin).lpNorm<Eigen::Infinity>(), 1e-300});
      worstSpinMismatch_ = std::max(worstSpinMismatch_, Eigen::Map<const Rows>(spin.data(), nd, 3).rowwise().norm().maxCoeff() / spinScale);
      const Eigen::Map<const Rows> torques(lambda.data() + 3 * nd, nd, 3);
      largestTorque_ = std::max(largestTorque_, torques.rowwise().norm().maxCoeff());
    }
    largestMultiplier_ = std::max(largestMultiplier_, spin_ ? Eigen::Map<const Rows>(lambda.data(), nd, 3).rowwise().norm().maxCoeff()
                                                            : lambda.rowwise().norm().maxCoeff());
    energies(host);
    return {2, residual, residual / scale, true, true};
  }

  bool strong() const override { return true; }
  std::string describe() const override {
    return fmt::format("bridging scheme{}, {} particles on {} overlap nodes{}", tie_ ? " (a tie, no multipliers)" : "",
                       map_->toSize(), map_->fromSize(),
                       spinOperator_.size() > 0 ? ", the spin tied if the particles rotate" : ", the spin free");
  }

  void archive(common::StateArchive& a) override {
    a.io("multiplier_work", multiplierWork_), a.io("worst_mismatch", worstMismatch_);
    a.io("largest_multiplier", largestMultiplier_), a.io("initial_energy", initialEnergy_);
    if (!a.reading() || a.has("worst_spin_mismatch"))  // a checkpoint from before the spin was tied has none
      a.io("worst_spin_mismatch", worstSpinMismatch_), a.io("largest_torque", largestTorque_);
    a.io("energy_drift", energyDrift_), a.io("energy_continuum", energyFem_), a.io("energy_particles", energyDem_);
  }

  void report(common::Summary& s) const override {
    s.set("bridging_particles", static_cast<std::int64_t>(map_->toSize()));
    s.set("bridging_nodes", static_cast<std::int64_t>(map_->fromSize()));
    s.set("bridging_velocity_mismatch", worstMismatch_);
    s.set("bridging_largest_multiplier_n", largestMultiplier_);
    s.set("bridging_rotations", std::string(spin_ ? "constrained" : "free"));
    if (spin_) {
      s.set("bridging_spin_mismatch", worstSpinMismatch_);
      s.set("bridging_largest_torque_nm", largestTorque_);
    }
    s.set("bridging_multiplier_work_j", multiplierWork_);
    s.set("bridging_solve_time_s", solveSeconds_);  // the multipliers: factor, mismatch, solve, forces
    s.set("bridging_setup_time_s", setupSeconds_);  // finding each particle's element (mapping, spin operator)
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

  // The spin is constrained where the continuum has a spin operator and the particles write their spin
  // and read a torque (a particle code without rotations declares neither).
  void chooseSpin(SchemeHost& host) {
    const bool spins = host.inputs(dem_).count("bridge/torque") > 0 && host.outputs(dem_).count("bridge/spin") > 0;
    if (rotations_ == Rotations::kConstrained && !spins)
      throw common::ConfigError(fmt::format("coupling.rotations: constrained, but participant \"{}\" does not write "
                                            "bridge/spin and read bridge/torque (its particles do not rotate)",
                                            host.name(dem_)));
    spin_ = spins && spinOperator_.size() > 0;
    spinChosen_ = true;
  }

  static void checkPositive(SchemeHost& host, std::size_t p, const std::vector<double>& values, const char* what) {
    for (double m : values)
      if (!(m > 0) || !std::isfinite(m))
        throw common::ConfigError(fmt::format("coupling.scheme: bridging: participant \"{}\" wrote a weighted {} {} "
                                              "in its overlap; every node needs a positive one (its bridging "
                                              "min_weight)",
                                              host.name(p), what, m));
  }

  // B = αM + Gᵀ diag(rowMass) G (multipliers()), factored again only when a weighted mass changed.
  void factor(SchemeHost& host) {
    const std::size_t nf = map_->fromSize(), nd = map_->toSize();
    const auto& mf = output(host, fem_, "bridge/mass", nf);
    const auto& md = output(host, dem_, "bridge/mass", nd);
    static const std::vector<double> kNone;
    const auto& id = spin_ ? output(host, dem_, "bridge/inertia", nd) : kNone;
    if (mf == massFem_ && md == massDem_ && id == inertiaDem_) return;
    checkPositive(host, fem_, mf, "mass");
    checkPositive(host, dem_, md, "mass");
    checkPositive(host, dem_, id, "moment of inertia");
    massFem_ = mf, massDem_ = md, inertiaDem_ = id;
    checkWeights(host);
    const auto n = static_cast<Eigen::Index>(nd);
    const Eigen::Map<const Eigen::VectorXd> particleMass(md.data(), n);
    if (!spin_) {
      G_ = Sparse(map_->matrix());
      rowMass_ = particleMass;
    } else {
      G_ = spinRows(Sparse(map_->matrix()));
      rowMass_.resize(6 * n);
      for (Eigen::Index j = 0; j < n; ++j) rowMass_.segment(3 * j, 3).setConstant(md[static_cast<std::size_t>(j)]);
      for (Eigen::Index j = 0; j < n; ++j) rowMass_.segment(3 * (n + j), 3).setConstant(id[static_cast<std::size_t>(j)]);
    }
    Sparse B = G_.transpose() * rowMass_.asDiagonal() * G_;
    const Eigen::Index per = spin_ ? 3 : 1;
    for (std::size_t i = 0; i < nf; ++i)
      for (Eigen::Index k = 0; k < per; ++k) B.coeffRef(per * static_cast<Eigen::Index>(i) + k, per * static_cast<Eigen::Index>(i) + k) += mf[i];
    solver_.compute(B);
    if (solver_.info() != Eigen::Success)
      throw common::ConfigError("coupling.scheme: bridging: the multiplier system could not be factored");
  }

  // α (the continuum's linear function interpolated at each particle, clamped to [0, 1] and shaped: the
  // continuum writes it unclamped, which its elements interpolate exactly) + β (the particle's) = 1: both
  // scenes describe the same zone.
  void checkWeights(SchemeHost& host) const {
    const std::size_t nf = map_->fromSize(), nd = map_->toSize();
    const auto& wf = output(host, fem_, "bridge/weight", nf);
    const auto& wd = output(host, dem_, "bridge/weight", nd);
    using Zone = common::BridgingZone;
    const auto& out = host.outputs(fem_);
    const auto code = out.find("bridge_energy/shape");
    const Zone::Shape shape = code != out.end() && !code->second.empty() && code->second[0] == 1.0 ? Zone::Shape::kCubic
                                                                                                 : Zone::Shape::kLinear;
    std::vector<double> alpha(nd);
    map_->consistent(wf, alpha, 1);
    for (double& a : alpha) a = Zone::shaped(shape, std::clamp(a, 0.0, 1.0));
    for (std::size_t j = 0; j < nd; ++j)
      if (std::abs(alpha[j] + wd[j] - 1.0) > 1e-6) {
        const Vec3& x = host.meshes(dem_).at("bridge").nodes[j];
        throw common::ConfigError(fmt::format(
            "coupling.scheme: bridging: at particle {} ({:.6g}, {:.6g}, {:.6g}) the continuum's weight is {:.6g} and "
            "the particles' {:.6g}; they must sum to 1 (the same `bridging` zone in both participants' scenes)",
            j, x.x(), x.y(), x.z(), alpha[j], wd[j]));
      }
  }

  // [N ⊗ I₃; C]: the translation rows particle-major (3j + k), then the spin rows, over the nodes'
  // velocities node-major (3i + k).
  Sparse spinRows(const Sparse& N) const {
    std::vector<Eigen::Triplet<double>> t;
    for (Eigen::Index c = 0; c < N.outerSize(); ++c)
      for (Sparse::InnerIterator it(N, c); it; ++it)
        for (Eigen::Index k = 0; k < 3; ++k) t.emplace_back(3 * it.row() + k, 3 * it.col() + k, it.value());
    const Eigen::Index shift = 3 * N.rows();
    for (Eigen::Index c = 0; c < spinOperator_.outerSize(); ++c)
      for (Sparse::InnerIterator it(spinOperator_, c); it; ++it) t.emplace_back(shift + it.row(), it.col(), it.value());
    Sparse G(6 * N.rows(), 3 * N.cols());
    G.setFromTriplets(t.begin(), t.end());
    return G;
  }

  // A⁻¹ g by Woodbury's identity: with D = diag(rowMass)⁻¹ and W = (αM)⁻¹, (D + G W Gᵀ)⁻¹ =
  // D⁻¹ − D⁻¹ G B⁻¹ Gᵀ D⁻¹, B = W⁻¹ + Gᵀ D⁻¹ G = αM + Gᵀ diag(rowMass) G, the overlap's coupled mass matrix:
  // a system of the nodes instead of the particles, which outnumber them (docs/validation/bridging.md: its
  // factor's non-zeros on the slab).
  Eigen::MatrixXd multipliers(const Eigen::MatrixXd& g) const {
    const Eigen::MatrixXd y = rowMass_.asDiagonal() * g;
    const Eigen::MatrixXd z = solver_.solve(Eigen::MatrixXd(G_.transpose() * y));
    return y - rowMass_.asDiagonal() * (G_ * z);
  }

  // N v − u per particle, from the last outputs: n_particles × 3, or with the spin one column of 6
  // n_particles, the translations particle-major and then C v − ω.
  Eigen::MatrixXd mismatch(SchemeHost& host) const {
    const std::size_t nf = map_->fromSize(), nd = map_->toSize();
    const auto& vf = output(host, fem_, "bridge/velocity", 3 * nf);
    const auto& ud = output(host, dem_, "bridge/velocity", 3 * nd);
    const auto n = static_cast<Eigen::Index>(nd);
    Rows g(n, 3);
    map_->consistent(vf, std::span<double>(g.data(), 3 * nd), 3);
    g -= Eigen::Map<const Rows>(ud.data(), n, 3);
    if (!spin_) return g;
    const auto& wd = output(host, dem_, "bridge/spin", 3 * nd);
    Eigen::VectorXd out(6 * n);
    out.head(3 * n) = Eigen::Map<const Eigen::VectorXd>(g.data(), 3 * n);
    out.tail(3 * n) = spinOperator_ * Eigen::Map<const Eigen::VectorXd>(vf.data(), static_cast<Eigen::Index>(3 * nf)) -
                      Eigen::Map<const Eigen::VectorXd>(wd.data(), 3 * n);
    return out;
  }

  static double largest(SchemeHost& host, std::size_t p, const std::string& field) {
    double most = 0.0;
    for (double v : host.outputs(p).at(field)) most = std::max(most, std::abs(v));
    return most;
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
  Rotations rotations_;
  bool spin_ = false, spinChosen_ = false;  // the particles' spin is constrained (chooseSpin())
  double energyTolerance_;
  std::size_t fem_ = 0, dem_ = 0;
  std::unique_ptr<Mapping> map_;
  Sparse spinOperator_;  // C: 3 n_particles × 3 n_nodes, empty where the continuum has no tetrahedra
  Sparse G_;             // the constraints' rows: N, or [N ⊗ I₃; C] with the spin
  Eigen::SimplicialLDLT<Sparse> solver_;  // of B (multipliers())
  Eigen::VectorXd rowMass_;               // the particles' weighted mass of each row of G_ (and inertia)
  std::vector<double> massFem_, massDem_, inertiaDem_;
  double solveSeconds_ = 0.0, setupSeconds_ = 0.0;
  double multiplierWork_ = 0.0, worstMismatch_ = 0.0, largestMultiplier_ = 0.0;
  double worstSpinMismatch_ = 0.0, largestTorque_ = 0.0;
  double initialEnergy_ = -1.0, energyDrift_ = 0.0, energyFem_ = 0.0, energyDem_ = 0.0;
};

}  // namespace

SchemeKeys readBridging(const common::Config& c, CouplingSpec& spec) {
  // `tie` slaves the particles of the overlap to the continuum (no multipliers: the continuum feels
  // nothing), to show what the multipliers do.
  const bool tie = c.choice("constraint", {"multipliers", "tie"}, "multipliers") == "tie";
  // `auto`: the spin is constrained where it can be (a continuum of tetrahedra, particles that rotate).
  const std::string r = c.choice("rotations", {"auto", "constrained", "free"}, "auto");
  const Rotations rotations = r == "free" ? Rotations::kFree : r == "constrained" ? Rotations::kConstrained : Rotations::kAuto;
  refuseIterationKeys(c, spec);
  return {[tie, rotations](const CouplingSpec& s, const SchemeHost& host) {
            return std::make_unique<Bridging>(s, host, tie, rotations);
          },
          {}};
}

}  // namespace cosim
