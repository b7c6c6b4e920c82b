#include "dem/simulation.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "dem/time_steps.hpp"
#include "contact_set.hpp"
#include "integrator.hpp"
#include "mesh_walls.hpp"
#include "neighbour_list.hpp"
#include "ordered_sum.hpp"
#include "plane_walls.hpp"
#include "sphere_pairs.hpp"
#include "step_context.hpp"

namespace dem {

namespace {
constexpr double kPi = 3.14159265358979323846;

// Adds the wall-clock time since the last lap (or the start) to a phase's sum (Simulation::Profile).
class Stopwatch {
 public:
  void lap(double& into) {
    const double now = omp_get_wtime();
    into += now - mark_;
    mark_ = now;
  }
  void restart() { mark_ = omp_get_wtime(); }

 private:
  double mark_ = omp_get_wtime();
};

using detail::orderedSum, detail::reduced;
}  // namespace

Simulation::Simulation()
    : neighbours_(std::make_unique<NeighbourList>()),
      pairs_(std::make_unique<SpherePairs>()),
      planeWalls_(std::make_unique<PlaneWalls>()),
      meshWalls_(std::make_unique<MeshWalls>()),
      integrator_(std::make_unique<Integrator>()) {}
Simulation::~Simulation() = default;

double Simulation::time() const { return integrator_->time(); }
std::int64_t Simulation::steps() const { return integrator_->steps(); }
Simulation::Profile Simulation::profile() const {
  Profile p = profile_;
  p.neighbourRebuilds = neighbours_->rebuilds();
  return p;
}

std::uint32_t Simulation::addCluster(const std::vector<Vec3>& local, const std::vector<double>& radii,
                                     std::uint32_t material, double mass, const Vec3& inertia, const Vec3& position,
                                     const Quat& orientation, const Vec3& velocity, const Vec3& angularVelocity,
                                     bool fixed) {
  const auto body = static_cast<std::uint32_t>(bodies_.size());
  const Eigen::Matrix3d R = orientation.toRotationMatrix();
  bodies_.position.push_back(position);
  bodies_.velocity.push_back(velocity);
  bodies_.angularVelocity.push_back(angularVelocity);
  bodies_.angularMomentum.push_back(R * inertia.asDiagonal() * R.transpose() * angularVelocity);
  bodies_.orientation.push_back(orientation.normalized());
  bodies_.mass.push_back(mass);
  bodies_.inertia.push_back(inertia);
  bodies_.force.push_back(Vec3::Zero());
  bodies_.torque.push_back(Vec3::Zero());
  bodies_.externalForce.push_back(Vec3::Zero());
  bodies_.fixed.push_back(fixed ? 1 : 0);
  bodies_.firstSphere.push_back(static_cast<std::uint32_t>(spheres_.size()));
  bodies_.sphereCount.push_back(static_cast<std::uint32_t>(local.size()));
  double reach = 0.0;
  for (const auto& l : local) reach = std::max(reach, l.norm());
  neighbours_->addBody(reach);
  for (std::size_t i = 0; i < local.size(); ++i) {
    spheres_.local.push_back(local[i]);
    spheres_.position.push_back(position + orientation * local[i]);
    spheres_.radius.push_back(radii[i]);
    spheres_.material.push_back(material);
    spheres_.body.push_back(body);
  }
  return body;
}

PlaneWallSet& Simulation::planeWalls() { return *planeWalls_; }
const PlaneWallSet& Simulation::planeWalls() const { return *planeWalls_; }
MeshWallSet& Simulation::meshWalls() { return *meshWalls_; }
const MeshWallSet& Simulation::meshWalls() const { return *meshWalls_; }

std::vector<std::pair<std::string, bool>> Simulation::physics() const {
  return {{"rotation", rotation_},
          {"friction", interactions_.anyFriction()},
          {"rolling_resistance", rolling_},
          {"sphere_pairs", neighbours_->pairsPossible()},
          {"plane_walls", !planeWalls_->empty()},
          {"mesh_walls", !meshWalls_->empty()},
          {"local_damping", settings_.localDamping > 0.0},
          {"cohesive_bonds", bonds_.created() > 0},
          {"lone_sphere_path", loneSpheres_}};
}

BondSet::View Simulation::bondView() const {
  return {centres().data(),          spheres_.radius.data(),   spheres_.body.data(), bodies_.position.data(),
          bodies_.velocity.data(),   bodies_.angularVelocity.data(), spheres_.size()};
}

void Simulation::formBonds() {
  COSIM_ASSERT(initialized_, "Simulation::formBonds() before initialize()");
  if (positionsStale_) updateSpherePositions(true);
  // The touching pairs' shear springs, by (a, b): their bonds start from them.
  const ContactSet& ss = pairs_->contacts();
  auto shearOf = [&](std::uint32_t a, std::uint32_t b) -> Vec3 {
    for (const auto& [begin, end] : ss.ranges) {
      const auto first = ss.a.begin() + static_cast<std::ptrdiff_t>(begin);
      const auto last = ss.a.begin() + static_cast<std::ptrdiff_t>(end);
      for (auto it = std::lower_bound(first, last, a); it != last && *it == a; ++it) {
        const auto k = static_cast<std::size_t>(it - ss.a.begin());
        if (ss.b[k] == b) return ss.overlap[k] > 0.0 ? ss.history[k].shearForce : Vec3::Zero();
      }
    }
    return Vec3::Zero();
  };
  createBonds(shearOf);
  rotation_ |= !bonds_.empty();
  rebuildContacts(true, false, false);  // the bonded pairs leave the contact candidates
}

void Simulation::createBonds(const BondSet::ShearOf& shearOf) {
  double rmax = 0.0;
  for (double r : spheres_.radius) rmax = std::max(rmax, r);
  double reach = 0.0;
  for (const auto& law : interactions_.laws())
    if (const BondingLaw* b = law->bonding()) reach = std::max(reach, b->bondReach(rmax, rmax));
  if (reach == 0.0) {
    bonds_ = BondSet{};
    return;
  }
  // On several ranks a bond is the rank's that computes its pair (NeighbourList::setOwners).
  auto lawOf = [&](std::uint32_t s, std::uint32_t t) { return neighbours_->computes(s, t) ? bondingLaw(s, t) : nullptr; };
  auto massOf = [&](std::uint32_t s, std::uint32_t t) {
    const auto a = spheres_.body[s], b = spheres_.body[t];
    return reduced(bodies_.mass[a], bodies_.mass[b], infiniteMass(bodies_.fixed[a]), infiniteMass(bodies_.fixed[b]));
  };
  bonds_.create(bondView(), lawOf, massOf, reach, shearOf);
}

void Simulation::resolveSkins() {
  if (settings_.skin <= 0.0) {
    const double rmin = spheres_.size() ? *std::min_element(spheres_.radius.begin(), spheres_.radius.end()) : 1.0;
    settings_.skin = 0.2 * rmin;
  }
  if (settings_.meshSkin <= 0.0) settings_.meshSkin = meshWalls_->automaticSkin(spheres_, settings_.skin);
  if (settings_.rankMargin <= 0.0) settings_.rankMargin = 4.0 * settings_.skin;
}

void Simulation::initialize() {
  resolveSkins();
  // Members of one rigid body never touch each other: a lone cluster has no sphere pairs to track.
  const bool oneBody = std::all_of(spheres_.body.begin(), spheres_.body.end(),
                                   [&](auto b) { return b == spheres_.body.front(); });  // none: true
  neighbours_->prepare(!oneBody);
  // A single sphere only starts rotating under friction; without it and without spin, skip rotation.
  rotation_ = false;
  for (const auto& w : bodies_.angularVelocity) rotation_ |= w.squaredNorm() > 0.0;
  for (auto c : bodies_.sphereCount) rotation_ |= c > 1;  // off-centre member contacts exert torque
  loneSpheres_ = loneScene_;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Vec3& I = bodies_.inertia[b];
    loneSpheres_ &= bodies_.sphereCount[b] == 1 && spheres_.local[bodies_.firstSphere[b]].squaredNorm() == 0.0 &&
                    I.x() == I.y() && I.y() == I.z();
  }
  integrator_->prepare(bodies_, loneSpheres_);
  rolling_ = interactions_.anyRolling();
  rotation_ = rotation_ || interactions_.anyFriction() || rolling_;
  // Lone spheres sum their contacts straight into their bodies' force and torque (forceSums()).
  sphereForce_.assign(loneSpheres_ ? 0 : spheres_.size(), Vec3::Zero());
  sphereTorque_.assign(loneSpheres_ ? 0 : spheres_.size(), Vec3::Zero());
  sphereForce_.shrink_to_fit(), sphereTorque_.shrink_to_fit();
  bodies_.shrinkToFit(), spheres_.shrinkToFit();
  updateSpherePositions(true);
  if (settings_.bondAtStart) createBonds();
  if (settings_.bridging) weighBridgingZone();
  rotation_ |= !bonds_.empty();  // a bond's shear force is off-centre
  rebuildContacts(true, true, true);
  computeForces();
  energy_ = EnergyLedger{};
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    if (bodies_.fixed[b]) continue;
    energy_.kinetic += 0.5 * bodies_.mass[b] * bodies_.velocity[b].squaredNorm() +
                       0.5 * bodies_.angularVelocity[b].dot(bodies_.angularMomentum[b]);
    energy_.potential -= bodies_.mass[b] * settings_.gravity.dot(bodies_.position[b]);
  }
  energy_.elastic = contactEnergies()[0] + bonds_.elasticEnergy();
  energy_.damping = energy_.friction = 0.0;  // the initial force pass dissipates nothing
  initialEnergy_ = energy_.total();
  initialApproach_ = dem::approachSpeedEstimate(*this);
  profile_ = Profile{};
  initialized_ = true;
}

StepContext Simulation::context() {
  return {settings_, interactions_.laws(), interactions_.table(), interactions_.materials().size(), bodies_, spheres_, centres().data(),
          forceSums().data(), torqueSums().data(), loneSpheres_, rotation_, rolling_};
}

std::array<const std::vector<ContactForce>*, 3> Simulation::contactForces() const {
  return {&pairs_->contacts().force, &planeWalls_->contacts().force, &meshWalls_->contacts().forces};
}

std::array<double, 3> Simulation::contactEnergies() const {
  std::array<double, 3> sums{};  // elastic, damping, friction
  if (pairs_->energySummed()) sums = pairs_->energy();
  for (const auto* forces : contactForces()) {
    const bool pairs = forces == &pairs_->contacts().force;
    if (pairs && pairs_->energySummed()) continue;
    if (forces == &planeWalls_->contacts().force && planeWalls_->energySummed()) {  // summed in their pass
      for (std::size_t k = 0; k < 3; ++k) sums[k] += planeWalls_->energy()[k];
      continue;
    }
    // Open sphere pairs add nothing; their stored forces are stale after steps that did not store them.
    const double* overlap = pairs ? pairs_->contacts().overlap.data() : nullptr;
    const ContactForce* f = forces->data();
    orderedSum(static_cast<std::ptrdiff_t>(forces->size()), sums, [&](std::ptrdiff_t i, std::array<double, 3>& sum) {
      if (overlap && overlap[i] <= 0.0) return;
      sum[0] += f[i].elasticEnergy;
      sum[1] += f[i].dampingEnergy;
      sum[2] += f[i].frictionEnergy;
    });
  }
  return sums;
}

void Simulation::updateSpherePositions(bool all) {
  // One rotation matrix per body, then a matrix–vector product per member: a quaternion rotation per
  // sphere costs twice as much, and a 22,000-sphere cluster does this every step.
  // Lone spheres have no member off their centre: no rotation to apply.
  const auto nb = static_cast<std::ptrdiff_t>(loneSpheres_ ? 0 : bodies_.size());
  bodyRotation_.resize(static_cast<std::size_t>(nb));
  if (loneSpheres_) bodyRotation_.shrink_to_fit();
#pragma omp parallel for schedule(static) if (nb > kParallelMin)
  for (std::ptrdiff_t b = 0; b < nb; ++b)
    if (bodies_.sphereCount[b] > 1) bodyRotation_[b] = bodies_.orientation[b].toRotationMatrix();
  auto place = [&](std::uint32_t s) {
    const auto b = spheres_.body[s];
    const Vec3& local = spheres_.local[s];
    if (bodies_.sphereCount[b] > 1) spheres_.position[s] = bodies_.position[b] + bodyRotation_[b] * local;
    else if (local.squaredNorm() > 0.0) spheres_.position[s] = bodies_.position[b] + bodies_.orientation[b] * local;
    else spheres_.position[s] = bodies_.position[b];
  };
  const std::vector<std::uint32_t>& active = neighbours_->active();
  const auto n = static_cast<std::ptrdiff_t>(all ? spheres_.size() : active.size());
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (std::ptrdiff_t i = 0; i < n; ++i) place(all ? static_cast<std::uint32_t>(i) : active[static_cast<std::size_t>(i)]);
  positionsStale_ = !all && active.size() < spheres_.size();
}

const Spheres& Simulation::spheres() const {
  // Placing the inactive spheres changes no state, only a cache of it.
  if (positionsStale_) const_cast<Simulation*>(this)->updateSpherePositions(true);
  return spheres_;
}

void Simulation::rebuildContacts(bool pairs, bool planeWalls, bool meshWalls) {
  neighbours_->countRebuild();
  if (positionsStale_) updateSpherePositions(true);
  if (pairs) {
    pairs_->assign(context(), neighbours_->findPairs(context(), bonds_));
    neighbours_->pairsBuilt(bodies_, loneSpheres_);
  }
  if (planeWalls) {
    planeWalls_->rebuildCandidates(context());
    neighbours_->planesBuilt(bodies_, loneSpheres_, planeWalls_->walls());
  }
  if (pairs || planeWalls) refsStale_ = true;  // built when bodyContacts() asks
  if (meshWalls) {
    meshWalls_->rebuildCandidates(context());
    neighbours_->meshBuilt(bodies_, loneSpheres_, meshWalls_->walls());
  }
  // Only the active spheres get forces computed; the others' stay zero.
  neighbours_->findActive(context(), pairs_->contacts(), planeWalls_->contacts(), meshWalls_->contacts(), bonds_);
}

void Simulation::rebuildReferences() const {
  refsStale_ = false;
  const std::size_t ns = spheres_.size();
  // Sphere → contact references, in a fixed order (sphere contacts first, then walls).
  refStart_.assign(ns + 1, 0);
  const ContactSet& pairs = pairs_->contacts();
  for (auto s : pairs.a) ++refStart_[s + 1];
  for (auto s : pairs.b) ++refStart_[s + 1];
  const ContactSet& walls = planeWalls_->contacts();
  for (auto s : walls.a) ++refStart_[s + 1];
  std::partial_sum(refStart_.begin(), refStart_.end(), refStart_.begin());
  refs_.resize(refStart_.back());
  std::vector<std::uint32_t> fill(refStart_.begin(), refStart_.end() - 1);
  for (std::uint32_t k = 0; k < pairs.size(); ++k) {
    refs_[fill[pairs.a[k]]++] = {k, 0, +1};
    refs_[fill[pairs.b[k]]++] = {k, 0, -1};
  }
  for (std::uint32_t k = 0; k < walls.size(); ++k) refs_[fill[walls.a[k]]++] = {k, 1, +1};
}

void Simulation::computeGeometry() {
  // Sphere pairs and planes: in computeForces, fused with their laws.
  if (!meshWalls_->empty()) meshWalls_->computeContacts(context());
}

void Simulation::applyRollingResistance() {
  // A couple per touching contact whose law has μ_r > 0, after the forces are summed to the spheres (its
  // dissipation joins the contact's friction energy, summed by step()). I = 2/5 m R² per sphere caps it.
  pairs_->applyRollingResistance(context());
  planeWalls_->applyRollingResistance(context());
  meshWalls_->applyRollingResistance(context());
}

void Simulation::computeForces() {
  // The contacts add their forces to the spheres in contact order (sphere pairs, then walls, then meshes;
  // for several threads see BatchLaw::spherePairs).
  Profile& phase = profile_;
  Stopwatch watch;
  // The bonds before the contacts: a pair whose bond breaks in this step is a contact candidate in it.
  // The step's sums are renewed even when every bond has broken. What breaking releases is booked here:
  // the initial pass's, if any, is then before the initial total (initialize() resets the ledger).
  if (bonds_.formed()) {
    const std::size_t broke = bonds_.compute(bondView(), settings_.dt);
    energy_.bondFracture += bonds_.releasedEnergy();
    if (broke > 0) rebuildContacts(true, false, false);
  }
  watch.lap(phase.sphereContacts);
  computeGeometry();
  watch.lap(phase.wallContacts);
  Vec3* force = forceSums().data();
  Vec3* torque = torqueSums().data();
  const std::vector<std::uint32_t>& active = neighbours_->active();
  const auto na = static_cast<std::ptrdiff_t>(active.size());
  if (const auto ns = static_cast<std::ptrdiff_t>(spheres_.size()); 2 * na >= ns) {
    // Most spheres touch something (a settled sample): all of them, in order, is less work than the
    // active ones through their indices (the others' sums are zero already).
#pragma omp parallel for schedule(static) if (ns > kParallelMin)
    for (std::ptrdiff_t i = 0; i < ns; ++i) force[i].setZero(), torque[i].setZero();
  } else {
#pragma omp parallel for schedule(static) if (na > kParallelMin)
    for (std::ptrdiff_t i = 0; i < na; ++i) {
      force[active[static_cast<std::size_t>(i)]].setZero();
      torque[active[static_cast<std::size_t>(i)]].setZero();
    }
  }
  watch.lap(phase.other);
  pairs_->computeForces(context(), phase.sphereContactsWait);
  if (!bonds_.empty()) bonds_.scatter(bondView(), force, rotation_ ? torque : nullptr);
  watch.lap(phase.sphereContacts);
  planeWalls_->computeContacts(context());
  meshWalls_->computeForces(context());
  watch.lap(phase.wallContacts);
  if (rolling_) applyRollingResistance();
  const std::vector<std::uint32_t>& activeStart = neighbours_->activeStart();
  const auto nb = static_cast<std::ptrdiff_t>(loneSpheres_ ? 0 : bodies_.size());  // lone: in integrate()
#pragma omp parallel for schedule(static) if (nb > kParallelMin)
  for (std::ptrdiff_t b = 0; b < nb; ++b) {
    Vec3 f = Vec3::Zero(), t = Vec3::Zero();
    for (std::uint32_t i = activeStart[b]; i < activeStart[b + 1]; ++i) {
      const std::uint32_t s = active[i];
      f += sphereForce_[s];
      t += sphereTorque_[s] + (spheres_.position[s] - bodies_.position[b]).cross(sphereForce_[s]);
    }
    bodies_.force[b] = f;
    bodies_.torque[b] = t;
  }
  watch.lap(phase.sphereContacts);
}

void Simulation::integrate() {
  const bool first = integrator_->steps() == 0;
  const Integrator::StepEnergy sums = integrator_->advance(bodies_, spheres_, settings_, rotation_, externalForces_);
  const double dt = settings_.dt;
  energy_.kinetic = sums.kinetic;
  initialEnergy_ += sums.shift;
  energy_.potential = sums.potential;
  if (!first) energy_.cundall += sums.cundall;  // booked like the external work: none before t = 0
  // The ledger's kinetic energy is the shadow form at the step's start, t: the work that matches it is
  // the work up to t, F·v(t−dt/2) dt for the step just ended (none before the first step).
  if (!first) energy_.externalWork += sums.external;
  positionsStale_ = true;  // the bodies moved: spheres() places the centres at the new time
  planeWalls_->move(dt, energy_.wallWork);
  meshWalls_->move(dt, energy_.wallWork);
}

void Simulation::addStepTorque(std::uint32_t body, const Vec3& torque) {
  if (!rotation_) return;  // the integrator moves no spin: a torque would do no work
  stepTorques_.emplace_back(body, bodies_.torque.at(body));
  bodies_.torque[body] += torque;
  // Booked as the external forces' (integrate()): the work up to the step's start, none before the first.
  if (integrator_->steps() > 0) energy_.externalWork += torque.dot(bodies_.angularVelocity[body]) * settings_.dt;
}

void Simulation::step() {
  prepareStep();
  finishStep();
}

void Simulation::prepareStep() {
  COSIM_ASSERT(initialized_, "Simulation::step() before initialize()");
  Profile& phase = profile_;
  Stopwatch watch;
  if (integrator_->steps() > 0) {
    if (!loneSpheres_) updateSpherePositions(false);  // lone spheres' centres are read from their bodies
    if (const auto what = neighbours_->needsRebuild(bodies_, loneSpheres_, settings_, planeWalls_->walls(), meshWalls_->walls());
        what.pairs || what.planes || what.mesh)
      rebuildContacts(what.pairs, what.planes, what.mesh);
    watch.lap(phase.neighbour);
    computeForces();
    watch.restart();
  }
  const std::array<double, 3> sums = contactEnergies();
  energy_.elastic = sums[0] + bonds_.elasticEnergy();
  energy_.damping += sums[1] + bonds_.dampingEnergy();
  energy_.friction += sums[2];
  watch.lap(phase.other);
}

void Simulation::finishStep() {
  Stopwatch watch;
  integrate();
  // The contacts' torques again: the next step zeroes only the sums of spheres in contact.
  for (auto it = stepTorques_.rbegin(); it != stepTorques_.rend(); ++it) bodies_.torque[it->first] = it->second;
  stepTorques_.clear();
  watch.lap(profile_.integrate);
  // A free body's non-finite position or velocity makes the kinetic or potential sum non-finite (0·inf
  // is NaN too); only then look for it. Fixed bodies move at their prescribed, finite velocities.
  if (!std::isfinite(energy_.kinetic + energy_.potential))
    for (std::size_t b = 0; b < bodies_.size(); ++b)
      if (!std::isfinite(bodies_.position[b].squaredNorm()) || !std::isfinite(bodies_.velocity[b].squaredNorm())) {
        const double critical = dem::criticalTimeStep(*this), safe = dem::safeTimeStep(*this, initialApproach_);
        const bool externalWalls = std::any_of(meshWalls_->walls().begin(), meshWalls_->walls().end(),
                                               [](const MeshWall& w) { return w.motion == MeshWall::Motion::kExternal; });
        const bool tooLarge = settings_.dt > safe;
        const std::string dtFix = common::wholeStepValue(settings_.endTime, safe);
        const std::string evidence = fmt::format(
            "its position or velocity is not finite after step {}; dt = {:.4g} s is {:.3g} × the critical step {:.4g} s",
            steps(), settings_.dt, settings_.dt / critical, critical);
        const std::string fix =
            tooLarge ? fmt::format("dt = {} s (at most dt_safety {} × critical and the contact duration at {:.3g} m/s "
                                   "over steps_per_contact {}; end_time in whole steps)",
                                   dtFix, settings_.dtSafety, initialApproach_, settings_.stepsPerContact)
            : externalWalls
                ? "the time step is safe, so the input diverged: a wall driven from outside moved wildly (a coupling "
                  "window that did not converge: lower coupling.time_window or tighten its tolerance; see the coupler's "
                  "warnings)"
                : "the time step is safe: check the prescribed motions and forces";
        throw common::InstabilityError({"non-finite state", fmt::format("body {}", b), time(), evidence, fix,
                                        tooLarge ? std::vector<std::string>{"dt=" + dtFix}
                                                 : std::vector<std::string>{}});
      }
}

BodyContacts Simulation::bodyContacts(std::uint32_t body) const {
  if (refsStale_) rebuildReferences();
  BodyContacts out;
  const std::vector<std::uint32_t>&active = neighbours_->active(), &activeStart = neighbours_->activeStart();
  for (std::uint32_t i = activeStart[body]; i < activeStart[body + 1]; ++i)
    for (std::uint32_t r = refStart_[active[i]]; r < refStart_[active[i] + 1]; ++r) {
      const Ref& ref = refs_[r];
      const ContactSet& set = ref.wall ? planeWalls_->contacts() : pairs_->contacts();
      const double overlap = ref.wall ? set.point[ref.index].overlap : pairs_->overlap(ref.index, spheres_);
      if (overlap > out.maxOverlap) {
        out.maxOverlap = overlap;
        out.law = interactions_.at(set.law[ref.index]);
        out.effRadius = ref.wall ? set.point[ref.index].effRadius : set.effRadius[ref.index];
        out.effMass = ref.wall ? set.point[ref.index].effMass : set.effMass[ref.index];
      }
      if (overlap <= 0.0) continue;
      ++out.count;
    }
  const MeshContacts& mc = meshWalls_->contacts();
  for (std::size_t i = 0; i < mc.contacts.size(); ++i) {
    if (spheres_.body[mc.contacts[i].sphere] != body) continue;
    const ContactPoint& p = mc.points[i];
    if (p.overlap > out.maxOverlap) {
      out.maxOverlap = p.overlap;
      out.law = interactions_.at(mc.contacts[i].law);
      out.effRadius = p.effRadius;
      out.effMass = p.effMass;
    }
    ++out.count;
  }
  out.force = bodies_.force[body];  // the sum of its contact forces (pairs and planes may not store theirs)
  return out;
}

std::uint32_t addSphere(Simulation& sim, const Vec3& position, double radius, std::uint32_t material,
                        const Vec3& velocity, const Vec3& angularVelocity, bool fixed) {
  const double mass = 4.0 / 3.0 * kPi * radius * radius * radius * sim.interactions().materials()[material].density;
  return sim.addCluster({Vec3::Zero()}, {radius}, material, mass, Vec3::Constant(0.4 * mass * radius * radius), position,
                        Quat::Identity(), velocity, angularVelocity, fixed);
}

Vec3 bodyVelocity(const Simulation& sim, std::uint32_t body) {
  const Bodies& bodies = sim.bodies();
  // v(t) = v(t − dt/2) + a(t) dt/2 needs the next force; the last acceleration instead is O(dt²) off.
  // Before the first step the stored velocity is the scene's v(0) itself.
  if (bodies.fixed[body] || sim.steps() == 0) return bodies.velocity[body];
  return bodies.velocity[body] + 0.5 * sim.settings().dt * (bodies.force[body] / bodies.mass[body] + sim.settings().gravity);
}

}  // namespace dem
