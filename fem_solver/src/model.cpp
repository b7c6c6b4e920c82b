#include "fem/model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <Eigen/SparseCholesky>
#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/log.hpp"
#include "elements/membrane_tri3.hpp"

namespace fem {

namespace {
const char* kAxis[] = {"x", "y", "z"};

double norm(const std::vector<double>& a, const std::vector<std::uint8_t>& fixed) {
  double s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (!fixed[i]) s += a[i] * a[i];
  return std::sqrt(s);
}

// The Newton step on the free dofs (`freeIndex`: each dof's row, −1 where fixed): K(u) du = −r, with K
// assembled from the blocks' tangents at u and factorised by LDLᵀ. A singular K is an error naming the
// node of the weakest pivot and the prestress level and load factor it happened at.
Eigen::VectorXd newtonStep(const std::vector<std::unique_ptr<Element>>& blocks, const std::vector<double>& u,
                           const std::vector<int>& freeIndex, int nfree, const std::vector<double>& r, double level,
                           double lambda) {
  std::vector<Triplet> triplets, freeTriplets;
  for (const auto& b : blocks) b->tangent(u, triplets);
  freeTriplets.reserve(triplets.size());
  for (const auto& t : triplets) {
    const int a = freeIndex[static_cast<std::size_t>(t.row())], c = freeIndex[static_cast<std::size_t>(t.col())];
    if (a >= 0 && c >= 0) freeTriplets.emplace_back(a, c, t.value());
  }
  Eigen::SparseMatrix<double> K(nfree, nfree);
  K.setFromTriplets(freeTriplets.begin(), freeTriplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(K);
  const Eigen::VectorXd& D = ldlt.vectorD();
  const double dmax = D.cwiseAbs().maxCoeff();
  Eigen::Index weakest = 0;
  const double dmin = D.cwiseAbs().minCoeff(&weakest);
  if (ldlt.info() != Eigen::Success || !(dmin > 1e-13 * dmax)) {
    // Map the weakest pivot back to its dof (the factorisation permutes rows).
    const Eigen::Index row = ldlt.permutationPinv().indices()(weakest);
    std::size_t dof = 0;
    for (std::size_t i = 0; i < freeIndex.size(); ++i)
      if (freeIndex[i] == row) dof = i;
    throw common::SimulationError(fmt::format(
        "static solve: the stiffness is singular at node {} ({}) (pivot {:.3g} vs largest {:.3g}; prestress level "
        "{:.4g} Pa, load factor {:.3g}). A flat membrane without prestress has no out-of-plane stiffness: give a "
        "prestress, use static.prestress_continuation, or support the node.",
        dof / 3, kAxis[dof % 3], dmin, dmax, level, lambda));
  }
  Eigen::VectorXd rhs(nfree);
  for (std::size_t i = 0; i < freeIndex.size(); ++i)
    if (freeIndex[i] >= 0) rhs(freeIndex[i]) = -r[i];
  return ldlt.solve(rhs);
}

}  // namespace

void Model::finalize() {
  const std::size_t n = dofs();
  fixed.resize(n, 0);
  prescribed.resize(n, 0.0);
  deadLoad.resize(n, 0.0);
  coupledForce.assign(n, 0.0);
  u_.assign(n, 0.0);
  v_.assign(n, 0.0);
  fint_.assign(n, 0.0);
  reaction_.assign(n, 0.0);
  mass_.assign(nodes(), 0.0);
  for (const auto& b : blocks) b->addLumpedMass(mass_);
  for (std::size_t i = 0; i < nodes(); ++i)
    for (int k = 0; k < 3; ++k) deadLoad[3 * i + static_cast<std::size_t>(k)] += mass_[i] * gravity[k];
  // Node → (block, slot) list, in block and element order: the fixed summation order of internal forces.
  slots_.resize(blocks.size());
  gatherStart_.assign(nodes() + 1, 0);
  for (const auto& b : blocks)
    for (auto nd : b->connectivity()) ++gatherStart_[nd + 1];
  std::partial_sum(gatherStart_.begin(), gatherStart_.end(), gatherStart_.begin());
  gather_.resize(gatherStart_.back());
  std::vector<std::uint32_t> fill(gatherStart_.begin(), gatherStart_.end() - 1);
  for (std::uint32_t bi = 0; bi < blocks.size(); ++bi) {
    const auto& conn = blocks[bi]->connectivity();
    slots_[bi].assign(3 * conn.size(), 0.0);
    for (std::uint32_t s = 0; s < conn.size(); ++s) gather_[fill[conn[s]]++] = {bi, s};
  }
  computeInternalForces(u_, fint_, &strainEnergy_);
  forcesStale_ = false;
}

std::vector<double> Model::positions() const {
  std::vector<double> x(dofs());
  for (std::size_t i = 0; i < nodes(); ++i)
    for (int k = 0; k < 3; ++k) x[3 * i + static_cast<std::size_t>(k)] = reference[i][k] + u_[3 * i + static_cast<std::size_t>(k)];
  return x;
}

void Model::computeInternalForces(const std::vector<double>& u, std::vector<double>& f, double* energy) const {
  double e = 0.0;
  auto& slots = const_cast<std::vector<std::vector<double>>&>(slots_);
  for (std::size_t b = 0; b < blocks.size(); ++b) e += blocks[b]->internalForces(u, slots[b]);
  f.resize(dofs());
  const auto nn = static_cast<std::ptrdiff_t>(nodes());
#pragma omp parallel for schedule(static) if (nn > 2048)
  for (std::ptrdiff_t i = 0; i < nn; ++i) {
    double fx = 0, fy = 0, fz = 0;
    for (std::uint32_t g = gatherStart_[i]; g < gatherStart_[i + 1]; ++g) {
      const auto [b, s] = gather_[g];
      const double* p = &slots_[b][3 * s];
      fx += p[0];
      fy += p[1];
      fz += p[2];
    }
    f[3 * i] = fx;
    f[3 * i + 1] = fy;
    f[3 * i + 2] = fz;
  }
  if (energy) *energy = e;
}

Vec3 Model::supportForce(std::uint32_t n) const {
  ensureForces();
  Vec3 r = Vec3::Zero();
  for (int k = 0; k < 3; ++k) {
    const std::size_t d = 3 * n + static_cast<std::size_t>(k);
    if (fixed[d]) r[k] = fint_[d] - deadLoad[d] - coupledForce[d];
  }
  return r;
}

// The free dofs' numbering, the membranes with their true prestress, the load and the work vectors of one
// static solve; newton() runs Newton–Raphson at one prestress level and load factor.
class Model::StaticSolve {
 public:
  StaticSolve(Model& model, const StaticSettings& s)
      : m_(model), s_(s), n_(model.dofs()), freeIndex_(n_, -1), r_(n_), load_(n_), trial_(n_),
        loadNorm_(std::max(norm(model.deadLoad, model.fixed) + norm(model.coupledForce, model.fixed), 1e-300)) {
    for (std::size_t i = 0; i < n_; ++i)
      if (!model.fixed[i]) freeIndex_[i] = nfree_++;
    for (auto& b : model.blocks)
      if (Prestressed* p = b->prestressed()) {
        membranes_.push_back(p);
        truePrestress_.push_back(p->prestress());
      }
  }

  bool hasMembranes() const { return !membranes_.empty(); }
  double largestTruePrestress() const {
    return truePrestress_.empty() ? 0.0 : *std::max_element(truePrestress_.begin(), truePrestress_.end());
  }
  /// level > 0: every membrane gets max(level, its own prestress); level 0: the true prestress.
  void setLevel(double level) {
    for (std::size_t m = 0; m < membranes_.size(); ++m)
      membranes_[m]->setPrestress(level > 0.0 ? std::max(level, truePrestress_[m]) : truePrestress_[m]);
  }

  /// Newton–Raphson with backtracking line search at one prestress level and load factor; leaves u_ at
  /// the last iterate and returns whether the relative residual fell below the tolerance. Counts its
  /// iterations into `report`.
  bool newton(double level, double lambda, StaticReport& report) {
    Model& m = m_;
    setLevel(level);
    for (std::size_t i = 0; i < n_; ++i) {
      load_[i] = lambda * m.deadLoad[i] + m.coupledForce[i];
      if (m.fixed[i]) m.u_[i] = lambda * m.prescribed[i];
    }
    scale_ = -1.0;
    double rel = residual(m.u_, r_);
    int it = 0;
    for (; it < s_.maxIterations && rel > s_.tolerance; ++it) {
      const Eigen::VectorXd du = newtonStep(m.blocks, m.u_, freeIndex_, nfree_, r_, level, lambda);
      // Backtracking line search on the residual norm: Newton steps on a slack membrane overshoot.
      double step = 1.0, trialRel = 0.0;
      for (int ls = 0; ls < 12; ++ls, step *= 0.5) {
        trial_ = m.u_;
        for (std::size_t i = 0; i < n_; ++i)
          if (freeIndex_[i] >= 0) trial_[i] += step * du(freeIndex_[i]);
        trialRel = residual(trial_, r_);
        if (std::isfinite(trialRel) && trialRel < rel) break;
      }
      m.u_ = trial_;
      rel = trialRel;
      ++report.iterations;
      log_->debug("  iteration {}: step {:.3g}, residual {:.3e}", it + 1, step, rel);
    }
    lastResidual_ = rel;
    lastIterations_ = it;
    const bool ok = std::isfinite(rel) && rel <= s_.tolerance;
    log_->debug("prestress level {:.4g} Pa, load factor {:.3f}: {} iterations, residual {:.3g}{}", level, lambda, it,
                rel, ok ? "" : " (not converged)");
    return ok;
  }

  double lastResidual() const { return lastResidual_; }

  [[noreturn]] void fail(double level, double lambda) const {
    throw common::SimulationError(fmt::format(
        "static solve did not converge: relative residual {:.3g} > tolerance {:.3g} after {} iterations (prestress "
        "level {:.4g} Pa, load factor {:.3g}). Use more load steps (static.load_steps), more iterations, or a larger "
        "static.prestress_continuation.",
        lastResidual_, s_.tolerance, lastIterations_, level, lambda));
  }

 private:
  // A solve driven by prescribed motion (no load: a pulled specimen) measures its residual against the
  // forces that motion causes at the moving supports when it is applied (first evaluation): the solution
  // itself may have none (a free end pulled along is a rigid translation).
  double residual(const std::vector<double>& u, std::vector<double>& out) {
    Model& m = m_;
    m.computeInternalForces(u, m.fint_, &m.strainEnergy_);
    double support = 0.0;
    for (std::size_t i = 0; i < n_; ++i) {
      out[i] = m.fixed[i] ? 0.0 : m.fint_[i] - load_[i];
      if (m.fixed[i] && m.prescribed[i] != 0.0) support += m.fint_[i] * m.fint_[i];
    }
    if (scale_ < 0.0) scale_ = std::max(loadNorm_, std::sqrt(support));
    return norm(out, m.fixed) / scale_;
  }

  Model& m_;
  const StaticSettings& s_;
  std::size_t n_;
  std::vector<int> freeIndex_;
  int nfree_ = 0;
  std::vector<Prestressed*> membranes_;
  std::vector<double> truePrestress_;
  std::vector<double> r_, load_, trial_;
  double loadNorm_;
  double scale_ = -1.0;
  double lastResidual_ = 0.0;
  int lastIterations_ = 0;
  std::shared_ptr<spdlog::logger> log_ = common::logger("fem.static");
};

StaticReport Model::solveStatic(const StaticSettings& s) {
  ensureForces();
  auto log = common::logger("fem.static");
  StaticReport report;
  StaticSolve solve(*this, s);
  if (s.method == StaticSettings::Method::kDynamicRelaxation) {
    solve.setLevel(0.0);
    for (std::size_t i = 0; i < dofs(); ++i)
      if (fixed[i]) u_[i] = s.loadFactor * prescribed[i];
    report.relaxationIterations = relax(s);
    report.residual = s.tolerance;
    return report;
  }
  // Load stepping at the first level: the continuation start, or the true prestress.
  const double maxTrue = solve.largestTruePrestress();
  double level = s.continuationStart > maxTrue && solve.hasMembranes() ? s.continuationStart : 0.0;
  for (int step = 1; step <= s.loadSteps; ++step) {
    const double lambda = s.loadFactor * static_cast<double>(step) / s.loadSteps;
    if (!solve.newton(level, lambda, report)) {
      if (level == 0.0 && step == s.loadSteps && s.fallback) {
        log->warn("Newton did not converge (residual {:.3g}); falling back to dynamic relaxation", solve.lastResidual());
        report.relaxationIterations = relax(s);
        report.residual = s.tolerance;
        return report;
      }
      solve.fail(level, lambda);
    }
    ++report.loadSteps;
  }
  ++report.stages;
  // Continuation: lower the prestress tenfold per stage; a stage that fails is retried from the last
  // converged state with a smaller reduction (√ of the last ratio).
  double ratio = 10.0;
  while (level > 0.0) {
    const double next = level / ratio > maxTrue ? level / ratio : 0.0;
    const std::vector<double> saved = u_;
    if (solve.newton(next, s.loadFactor, report)) {
      level = next;
      ++report.stages;
      ratio = std::min(10.0, ratio * ratio);
    } else if (next == 0.0 && s.fallback && ratio < 1.5) {
      log->warn("continuation stalled before the true prestress; finishing with dynamic relaxation");
      solve.setLevel(0.0);
      report.relaxationIterations = relax(s);
      break;
    } else {
      u_ = saved;
      ratio = std::sqrt(ratio);
      if (ratio < 1.05) solve.fail(next, s.loadFactor);
      log->debug("continuation: retrying from {:.4g} Pa with ratio {:.3g}", level, ratio);
    }
  }
  report.residual = solve.lastResidual();
  computeInternalForces(u_, fint_, &strainEnergy_);
  forcesStale_ = false;
  return report;
}

int Model::relax(const StaticSettings& s) {
  ensureForces();
  // Dynamic relaxation with kinetic damping (Barnes 1999; Underwood 1983): unit time step, fictitious
  // nodal masses m_i = ½ max over the node's rows of Σ_j |K_ij| (Gershgorin bound, so Δt = 1 is stable), and
  // every time the kinetic energy passes a peak the velocities are zeroed and the state is moved back
  // to the peak. Needs no factorisation, so it also works where the tangent is singular.
  const std::size_t n = dofs();
  const double loadNorm = std::max(s.loadFactor * norm(deadLoad, fixed) + norm(coupledForce, fixed), 1e-300);
  std::vector<double> mass(n), vel(n, 0.0), r(n), load(n);
  for (std::size_t i = 0; i < n; ++i) load[i] = s.loadFactor * deadLoad[i] + coupledForce[i];
  auto updateMass = [&] {
    std::vector<Triplet> t;
    for (const auto& b : blocks) b->tangent(u_, t);
    std::fill(mass.begin(), mass.end(), 0.0);
    for (const auto& tr : t) mass[static_cast<std::size_t>(tr.row())] += std::abs(tr.value());
    // One mass per node (the largest of its three rows): a slack direction must not get a tiny mass.
    for (std::size_t i = 0; i < n; i += 3) {
      const double m = std::max({0.5 * mass[i], 0.5 * mass[i + 1], 0.5 * mass[i + 2], 1e-300});
      mass[i] = mass[i + 1] = mass[i + 2] = m;
    }
  };
  updateMass();
  double previousKinetic = 0.0;
  for (int it = 1; it <= s.relaxationIterations; ++it) {
    computeInternalForces(u_, fint_, &strainEnergy_);
    forcesStale_ = false;
    for (std::size_t i = 0; i < n; ++i) r[i] = fixed[i] ? 0.0 : load[i] - fint_[i];
    const double rel = norm(r, fixed) / loadNorm;
    if (rel <= s.tolerance) return it;
    double kinetic = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (fixed[i]) continue;
      vel[i] += r[i] / mass[i];
      kinetic += 0.5 * mass[i] * vel[i] * vel[i];
    }
    if (kinetic < previousKinetic) {
      // Peak passed: step back half a step to the peak (approximately) and restart from rest.
      for (std::size_t i = 0; i < n; ++i)
        if (!fixed[i]) u_[i] -= 0.5 * (vel[i] - r[i] / mass[i]);
      std::fill(vel.begin(), vel.end(), 0.0);
      previousKinetic = 0.0;
      if (it % 50 == 0) updateMass();  // stiffness changes as the membrane tightens
      continue;
    }
    previousKinetic = kinetic;
    for (std::size_t i = 0; i < n; ++i)
      if (!fixed[i]) u_[i] += vel[i];
  }
  computeInternalForces(u_, fint_, &strainEnergy_);
  forcesStale_ = false;
  for (std::size_t i = 0; i < n; ++i) r[i] = fixed[i] ? 0.0 : load[i] - fint_[i];
  throw common::SimulationError(fmt::format(
      "dynamic relaxation did not converge: relative residual {:.3g} > tolerance {:.3g} after {} iterations "
      "(static.relaxation_iterations).",
      norm(r, fixed) / loadNorm, s.tolerance, s.relaxationIterations));
}

std::string Model::shape() const {
  std::string blocksText;
  for (const auto& b : blocks) blocksText += fmt::format("{}{} × {}", blocksText.empty() ? "" : ", ", b->size(), b->name());
  return fmt::format("{} nodes, blocks [{}]", nodes(), blocksText);
}

void Model::restoreState(const State& s) {
  if (s.u.size() != dofs() || s.v.size() != dofs())
    throw common::ConfigError(fmt::format("the saved state has {} displacement and {} velocity values; this model has {} "
                                          "dofs",
                                          s.u.size(), s.v.size(), dofs()));
  u_ = s.u;
  v_ = s.v;
  time_ = s.time;
  steps_ = s.steps;
  timeBase_ = s.timeBase;
  stepsBase_ = s.stepsBase;
  energy_ = s.energy;
  dt_ = s.dt;
  lastDt_ = s.lastDt;
  if (s.fint.size() == dofs()) {
    fint_ = s.fint;
    strainEnergy_ = s.strainEnergy;
    forcesStale_ = false;
  } else {
    computeInternalForces(u_, fint_, &strainEnergy_);
    forcesStale_ = false;
  }
}

void Model::setDisplacement(const std::vector<double>& u) {
  if (u.size() != dofs())
    throw common::SimulationError(
        fmt::format("the saved state has {} displacement values; this model has {} dofs.", u.size(), dofs()));
  u_ = u;
  computeInternalForces(u_, fint_, &strainEnergy_);
  forcesStale_ = false;
}

double Model::criticalTimeStep() const {
  double dt = std::numeric_limits<double>::infinity();
  for (const auto& b : blocks) dt = std::min(dt, b->criticalTimeStep());
  return dt;
}

void Model::setTimeStep(double dt) {
  if (dt == dt_) return;
  timeBase_ = time_;
  stepsBase_ = steps_;
  dt_ = dt;
}

Model::Current Model::current() const {
  Current out{std::numeric_limits<double>::infinity(), 0, 0, std::numeric_limits<double>::infinity()};
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const Element::Current c = blocks[b]->current(u_);
    out.criticalTimeStep = std::min(out.criticalTimeStep, c.criticalTimeStep);
    if (c.jacobian < out.jacobian) out.jacobian = c.jacobian, out.block = b, out.element = c.element;
  }
  return out;
}

void Model::initializeExplicit(double dt) {
  // The velocity at t = 0 is v(0): the first kick is a half kick, v(dt/2) = v(0) + a(0) dt/2.
  dt_ = dt;
  lastDt_ = 0.0;
  time_ = timeBase_ = 0.0;
  steps_ = stepsBase_ = 0;
  if (initialVelocity.size() == v_.size()) v_ = initialVelocity;
  else std::fill(v_.begin(), v_.end(), 0.0);
  computeInternalForces(u_, fint_, &strainEnergy_);
  forcesStale_ = false;
  energy_ = EnergyState{};
  energy_.strain = strainEnergy_;
  for (std::size_t i = 0; i < v_.size(); ++i) energy_.kinetic += 0.5 * mass_[i / 3] * v_[i] * v_[i];
}

void Model::stepExplicit() {
  ensureForces();
  const std::size_t n = dofs();
  // Stiffness-proportional damping β K v by a directional difference of the internal forces (the
  // scratch vectors are sized once: the step allocates nothing).
  const std::vector<double>& kv = fshift_;
  if (beta > 0.0) {
    const double eps = 1e-7;
    shifted_.resize(n);
    for (std::size_t i = 0; i < n; ++i) shifted_[i] = u_[i] + eps * v_[i];
    computeInternalForces(shifted_, fshift_, nullptr);
    for (std::size_t i = 0; i < n; ++i) fshift_[i] = (fshift_[i] - fint_[i]) / eps;
  }
  // The ledger is reported at time t_n: kinetic ½ m v(t−dt/2)·v(t+dt/2) (leapfrog shadow form), strain
  // energy at u_n, and the work of the loads up to t_n, Σ f·v(t_k − dt/2) dt.
  const double strainN = strainEnergy_;
  // Variable step: the kick spans half the last step and half this one (equal steps: exactly dt_).
  const double kick = 0.5 * (lastDt_ + dt_), last = lastDt_;
  const bool first = last == 0.0;
  double kinetic = 0.0, work = 0.0, dissipated = 0.0, coupledWork = 0.0, shift = 0.0;
  const auto nd = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static) reduction(+ : kinetic, work, dissipated, coupledWork, shift) if (nd > 6000)
  for (std::ptrdiff_t ii = 0; ii < nd; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const double m = mass_[i / 3];
    if (m <= 0.0) {
      v_[i] = 0.0;
      reaction_[i] = 0.0;
      continue;
    }
    const double damping = alpha * m * v_[i] + (beta > 0.0 ? beta * kv[i] : 0.0);
    double load = deadLoad[i] + coupledForce[i];
    const double v0 = v_[i];
    double v1;
    if (fixed[i]) {
      // A prescribed dof moves to its target in this step; the support supplies what the node's own
      // inertia, damping and internal force need (m a + f_int + damping − load): its node mass is the
      // support's, which is how a Dirichlet coupling interface carries its side's inertia.
      v1 = (prescribed[i] - u_[i]) / dt_;
      reaction_[i] = m * (v1 - v0) / kick + fint_[i] + damping - load;
      load += reaction_[i];
      u_[i] = prescribed[i];
    } else {
      v1 = v0 + kick * (load - fint_[i] - damping) / m;
      u_[i] += dt_ * v1;
    }
    v_[i] = v1;
    // From rest at t = 0 the shadow form needs v(−dt/2) = v(0) − a(0) dt/2 = 2 v(0) − v(dt/2).
    const double vm = first ? 2.0 * v0 - v1 : v0;
    kinetic += 0.5 * m * vm * v1;
    if (first) shift += 0.5 * m * (vm * v1 - v0 * v0);
    work += load * v0 * last;
    coupledWork += coupledForce[i] * v0 * last;
    dissipated += damping * v0 * last;
  }
  energy_.kinetic = kinetic;
  energy_.initialShift += shift;
  energy_.strain = strainN;
  energy_.externalWork += work;
  energy_.damping += dissipated;
  energy_.coupledWork += coupledWork;
  forcesStale_ = true;  // computed when next needed (ensureForces)
  ++steps_;
  lastDt_ = dt_;
  time_ = timeBase_ + static_cast<double>(steps_ - stepsBase_) * dt_;
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(u_[i])) {
      const double safe = 0.9 * criticalTimeStep();
      const bool tooLarge = dt_ > safe;
      const std::string dtFix = common::fixValue(safe);
      throw common::InstabilityError(
          {"non-finite state", fmt::format("node {} ({})", i / 3, kAxis[i % 3]), time_,
           fmt::format("its displacement is not finite after step {}; dt = {:.4g} s, the stable step of the reference "
                       "configuration {:.4g} s",
                       steps_, dt_, criticalTimeStep()),
           tooLarge
               ? fmt::format("explicit.dt = {} s (0.9 × the reference stable step, rounded down), or leave dt out: "
                             "explicit.dt_fraction follows the stable step as the structure deforms",
                             dtFix)
               : fmt::format("not the time step (dt = {:.4g} s is below 0.9 × the reference stable step): the loads or, "
                             "in a coupled run, the interface forces drove it (a smaller coupling.time_window, a tighter "
                             "coupling tolerance or an implicit scheme)",
                             dt_),
           tooLarge ? std::vector<std::string>{"explicit.dt=" + dtFix} : std::vector<std::string>{}});
    }
}

}  // namespace fem
