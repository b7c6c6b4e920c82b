#include "dem/simulation.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/geometry.hpp"
#include "avx2_rows.hpp"
#include "contact/tangential.hpp"
#include "contact_set.hpp"
#include "integrator.hpp"
#include "ordered_sum.hpp"
#include "plane_walls.hpp"
#include "step_context.hpp"
#include "mesh_walls.hpp"

namespace dem {

namespace {
// Above this many lone spheres the contact pass prefetches (SpherePairView::prefetch): their per-sphere
// arrays (120 bytes a sphere) no longer fit the per-core L2 cache with the candidates' state.
constexpr std::size_t kPrefetchSpheres = 20000;
constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Adds the wall-clock time since the last lap (or the start) to a phase's sum (Simulation::PhaseSeconds).
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

// What needsRebuildLone's first pass finds: the box of the displacements since the pair build, the
// largest of them and the largest since the plane build (squared).
struct Displacements {
  double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
  double absolute2 = 0.0, plane2 = 0.0;
};

using detail::joinInOrder, detail::orderedSum, detail::reduced;
#if defined(__x86_64__) && defined(__GNUC__)
using detail::loadRows, detail::rowDots;
#endif

// Bodies [b0, b1) into `d`. (Each maximum and minimum is exact, so the order of the bodies does not
// matter: four at a time below, any thread split.)
void displacementsScalar(const Vec3* x, const Vec3* atPairs, const Vec3* atPlanes, std::ptrdiff_t b0, std::ptrdiff_t b1,
                         Displacements& d) {
  for (std::ptrdiff_t b = b0; b < b1; ++b) {
    const Vec3 e = x[b] - atPairs[b];
    for (int c = 0; c < 3; ++c) d.lo[c] = std::min(d.lo[c], e[c]), d.hi[c] = std::max(d.hi[c], e[c]);
    d.absolute2 = std::max(d.absolute2, e.x() * e.x() + e.y() * e.y() + e.z() * e.z());  // as rowDots
    if (atPlanes) {
      const Vec3 f = x[b] - atPlanes[b];
      d.plane2 = std::max(d.plane2, f.x() * f.x() + f.y() * f.y() + f.z() * f.z());
    }
  }
}
#if defined(__x86_64__) && defined(__GNUC__)
// The same four bodies at a time, on their Vec3 rows as they lie in memory (integrateLoneFourAvx2).
// Returns where it stopped (fewer than four left).
DEM_TARGET_AVX2 std::ptrdiff_t displacementsAvx2(const Vec3* x, const Vec3* atPairs, const Vec3* atPlanes,
                                                 std::ptrdiff_t b0, std::ptrdiff_t b1, Displacements& d) {
  __m256d lo[3], hi[3];
  for (int r = 0; r < 3; ++r) lo[r] = _mm256_set1_pd(kInf), hi[r] = _mm256_set1_pd(-kInf);
  __m256d absolute2 = _mm256_setzero_pd(), plane2 = _mm256_setzero_pd();
  std::ptrdiff_t b = b0;
  for (; b + 4 <= b1; b += 4) {
    __m256d xr[3], pr[3], e[3];
    loadRows(x[b].data(), xr), loadRows(atPairs[b].data(), pr);
    for (int r = 0; r < 3; ++r) {
      e[r] = _mm256_sub_pd(xr[r], pr[r]);
      lo[r] = _mm256_min_pd(lo[r], e[r]), hi[r] = _mm256_max_pd(hi[r], e[r]);
    }
    absolute2 = _mm256_max_pd(absolute2, rowDots(e, e));
    if (atPlanes) {
      loadRows(atPlanes[b].data(), pr);
      for (int r = 0; r < 3; ++r) e[r] = _mm256_sub_pd(xr[r], pr[r]);
      plane2 = _mm256_max_pd(plane2, rowDots(e, e));
    }
  }
  // Lane j of row r holds component (4r + j) mod 3.
  alignas(32) double l[3][4], h[3][4], a[4], p[4];
  for (int r = 0; r < 3; ++r) _mm256_store_pd(l[r], lo[r]), _mm256_store_pd(h[r], hi[r]);
  _mm256_store_pd(a, absolute2), _mm256_store_pd(p, plane2);
  for (int r = 0; r < 3; ++r)
    for (int j = 0; j < 4; ++j) {
      const int c = (4 * r + j) % 3;
      d.lo[c] = std::min(d.lo[c], l[r][j]), d.hi[c] = std::max(d.hi[c], h[r][j]);
    }
  for (int j = 0; j < 4; ++j) d.absolute2 = std::max(d.absolute2, a[j]), d.plane2 = std::max(d.plane2, p[j]);
  return b;
}
#endif

// The spheres in cell order as the candidate search reads them (rebuildPairCandidates): centres and radii
// as structure of arrays, and each one's index. Eight entries past the last are read, not used.
struct CellOrdered {
  std::vector<double> x, y, z, r;
  std::vector<std::uint32_t> index;
  void resize(std::size_t n) {
    x.resize(n + 8), y.resize(n + 8), z.resize(n + 8), r.resize(n + 8), index.resize(n + 8);
  }
};

// The partners j > i of sphere i (centre xi, radius ri) among the cell-ordered spheres [k0, k1): those
// within ri + r_j + skin, appended to out[n ..] in the order met. Returns the new count. Every sphere is
// tested and written, and the count advanced only for a partner: a fifth of the tests pass, in no pattern
// the branch predictor learns.
std::size_t partnersScalar(const CellOrdered& c, std::uint32_t k0, std::uint32_t k1, std::uint32_t i, const Vec3& xi,
                           double ri, double skin, std::uint32_t* out, std::size_t n) {
  for (std::uint32_t k = k0; k < k1; ++k) {
    const std::uint32_t j = c.index[k];
    const double reach = ri + c.r[k] + skin;
    const double dx = xi.x() - c.x[k], dy = xi.y() - c.y[k], dz = xi.z() - c.z[k];
    out[n] = j;
    n += static_cast<std::size_t>((j > i) & (dx * dx + dy * dy + dz * dz < reach * reach));
  }
  return n;
}
#if defined(__x86_64__) && defined(__GNUC__)
// partnersScalar's test for four spheres from k (`left` of the run from there; lanes past it are unused):
// the partners' lanes packed to the front with a permutation and stored whole at out + n (room for four
// past the last partner).
struct PartnersFour {
  const CellOrdered& c;
  __m256d x, y, z, r, skin;
  __m128i sign, i;  // j > i unsigned, as a signed comparison of both with the sign bit flipped
  std::uint32_t* out;
  std::size_t n = 0;

  [[gnu::always_inline]] DEM_TARGET_AVX2 inline void operator()(std::uint32_t k, std::int64_t left) {
    static constexpr auto kPack = [] {  // per 4-bit mask of partner lanes, the lanes in order
      std::array<std::array<int, 4>, 16> p{};
      for (int m = 0; m < 16; ++m)
        for (int l = 0, o = 0; l < 4; ++l)
          if (m & (1 << l)) p[m][o++] = l;
      return p;
    }();
    const __m256d dx = _mm256_sub_pd(x, _mm256_loadu_pd(c.x.data() + k));
    const __m256d dy = _mm256_sub_pd(y, _mm256_loadu_pd(c.y.data() + k));
    const __m256d dz = _mm256_sub_pd(z, _mm256_loadu_pd(c.z.data() + k));
    const __m256d d2 =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
    const __m256d reach = _mm256_add_pd(_mm256_add_pd(r, _mm256_loadu_pd(c.r.data() + k)), skin);
    const __m128i j = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c.index.data() + k));
    const int after = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(_mm_xor_si128(j, sign), i)));
    const int near = _mm256_movemask_pd(_mm256_cmp_pd(d2, _mm256_mul_pd(reach, reach), _CMP_LT_OQ));
    const int mask = near & after & (0xf >> (4 - std::clamp<std::int64_t>(left, 0, 4)));
    const __m128i lanes = _mm_loadu_si128(reinterpret_cast<const __m128i*>(kPack[mask].data()));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + n),
                     _mm_castps_si128(_mm_permutevar_ps(_mm_castsi128_ps(j), lanes)));
    n += static_cast<std::size_t>(__builtin_popcount(static_cast<unsigned>(mask)));
  }
};

// partnersScalar for the 9 runs [k0[r], k1[r]) around a sphere, four spheres at a time. Each run takes
// two steps of four whatever its length: a run holds about 4.5 spheres, and a loop leaving after one or
// two steps mispredicted its exit at most runs, which cost more than the tests. Returns the count.
DEM_TARGET_AVX2 std::size_t partnersAvx2(const CellOrdered& c, const std::uint32_t* k0, const std::uint32_t* k1,
                                         std::uint32_t i, const Vec3& xi, double ri, double skin, std::uint32_t* out) {
  const __m128i sign = _mm_set1_epi32(static_cast<int>(0x80000000u));
  PartnersFour four{c,
                    _mm256_set1_pd(xi.x()),
                    _mm256_set1_pd(xi.y()),
                    _mm256_set1_pd(xi.z()),
                    _mm256_set1_pd(ri),
                    _mm256_set1_pd(skin),
                    sign,
                    _mm_xor_si128(_mm_set1_epi32(static_cast<int>(i)), sign),
                    out};
  for (int r = 0; r < 9; ++r) {
    const std::uint32_t k = k0[r];
    const auto left = static_cast<std::int64_t>(k1[r]) - k;
    four(k, left);
    four(k + 4, left - 4);
    for (std::int64_t more = 8; more < left; more += 4) four(k + static_cast<std::uint32_t>(more), left - more);
  }
  return four.n;
}
#endif
}  // namespace


// Not in a Checkpoint: nothing here outlives a build.
struct Simulation::BuildScratch {
  ContactSet::Spare pairs;
  std::vector<std::vector<Triple>> local;  // per thread, its candidates
  std::vector<Triple> joined;              // the threads' lists joined in order
  std::vector<unsigned char> inCandidate;  // per sphere
  CellOrdered cellOrdered;                 // the pair search's copies of the spheres
  std::vector<std::uint32_t> cellStart, cellIndex;  // per cell its first sphere in cell order; per sphere its cell
  std::vector<std::uint32_t> threadCount;  // per thread, its active spheres
};

// What a coupling iteration needs to start a window again. Not the spheres (only their centres change, and
// those follow from the bodies) nor the per-step force scratch: a 22,000-sphere block is restored
// thousands of times per run.
struct Simulation::Checkpoint {
  Bodies bodies;
  PlaneWalls planes;
  MeshWalls meshes;
  BondSet bonds;
  ContactSet sphereContacts;
  Poses atPairs, atPlanes, atMesh;
  std::vector<Vec3> planePointsAtBuild;
  std::vector<std::uint32_t> active, activeStart;
  std::vector<std::vector<Vec3>> meshNodesAtBuild;
  Integrator integrator;
  std::int64_t rebuilds;
  EnergyLedger energy;
  double initialEnergy;  // moved by the first step's shadow-energy shift
  std::array<double, 3> pairEnergy;
  bool pairEnergySummed;
  bool rotation;  // formBonds() may switch it on
  void archive(common::StateArchive& a) {
    a.io("bodies", bodies), a.io("planes", planes), a.io("meshes", meshes);
    a.io("bonds", bonds), a.io("sphere_contacts", sphereContacts), a.io("poses_at_pairs", atPairs);
    a.io("poses_at_planes", atPlanes);
    a.io("poses_at_mesh", atMesh), a.io("plane_points_at_build", planePointsAtBuild), a.io("active", active);
    a.io("active_start", activeStart), a.io("mesh_nodes_at_build", meshNodesAtBuild);
    a.io("integrator", integrator), a.io("rebuilds", rebuilds);
    a.io("energy", energy), a.io("initial_energy", initialEnergy), a.io("pair_energy", pairEnergy);
    a.io("pair_energy_summed", pairEnergySummed), a.io("rotation", rotation);
  }
};

void Simulation::archive(common::StateArchive& a) {
  a.shape(shape());
  auto scope = a.scope("simulation");
  if (!a.reading()) {
    Checkpoint c = *saveCheckpoint();
    c.archive(a);
    return;
  }
  Checkpoint c{};
  c.archive(a);
  if (c.bodies.size() != bodies_.size() || c.meshes.walls().size() != meshes().size() ||
      c.planes.walls().size() != planes().size())
    throw common::ConfigError(fmt::format("{}: the checkpoint holds {} bodies, {} plane and {} mesh walls; this scene has "
                                          "{}, {} and {}: not a checkpoint of this scene",
                                          a.path().string(), c.bodies.size(), c.planes.walls().size(),
                                          c.meshes.walls().size(), bodies_.size(), planes().size(), meshes().size()));
  restoreCheckpoint(c);
  const std::size_t nm = materials_.size();
  bonds_.relink([&](std::uint32_t s, std::uint32_t t) { return bondingLaw(s, t, nm); });
}

std::shared_ptr<const Simulation::Checkpoint> Simulation::saveCheckpoint() const {
  return std::make_shared<const Checkpoint>(Checkpoint{
      bodies_, *planeWalls_, *meshWalls_, bonds_, *sphereContacts_,
      atPairs_, atPlanes_, atMesh_, planePointsAtBuild_, active_,
      activeStart_, meshNodesAtBuild_, *integrator_, rebuilds_, energy_, initialEnergy_,
      pairEnergy_, pairEnergySummed_, rotation_});
}

void Simulation::restoreCheckpoint(const Checkpoint& c) {
  bodies_ = c.bodies;
  *planeWalls_ = c.planes;
  *meshWalls_ = c.meshes;
  bonds_ = c.bonds;
  *sphereContacts_ = c.sphereContacts;
  refsStale_ = true;
  atPairs_ = c.atPairs;
  atPlanes_ = c.atPlanes;
  atMesh_ = c.atMesh;
  active_ = c.active;
  activeStart_ = c.activeStart;
  positionsStale_ = true;  // the centres are still those of the later state
  pairEnergy_ = c.pairEnergy;
  pairEnergySummed_ = c.pairEnergySummed;
  rotation_ = c.rotation;
  // Spheres inactive here must not keep the sums of the later state (lone spheres: their sums are the
  // bodies' forces, restored above).
  std::fill(sphereForce_.begin(), sphereForce_.end(), Vec3::Zero());
  std::fill(sphereTorque_.begin(), sphereTorque_.end(), Vec3::Zero());
  planePointsAtBuild_ = c.planePointsAtBuild;
  meshNodesAtBuild_ = c.meshNodesAtBuild;
  *integrator_ = c.integrator;
  rebuilds_ = c.rebuilds;
  initialEnergy_ = c.initialEnergy;
  energy_ = c.energy;
}

Simulation::Simulation()
    : meshWalls_(std::make_unique<MeshWalls>()),
      integrator_(std::make_unique<Integrator>()),
      sphereContacts_(std::make_unique<ContactSet>()),
      planeWalls_(std::make_unique<PlaneWalls>()),
      scratch_(std::make_unique<BuildScratch>()) {}
Simulation::~Simulation() = default;

double Simulation::time() const { return integrator_->time(); }
std::int64_t Simulation::steps() const { return integrator_->steps(); }

std::uint32_t Simulation::addMaterial(const Material& m) {
  const auto n = materials_.size();
  std::vector<int> grown((n + 1) * (n + 1), -1);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) grown[i * (n + 1) + j] = lawOf_[i * n + j];
  lawOf_ = std::move(grown);
  materials_.push_back(m);
  return static_cast<std::uint32_t>(n);
}

void Simulation::setInteraction(std::uint32_t a, std::uint32_t b, std::unique_ptr<ContactLaw> law) {
  const auto n = materials_.size();
  COSIM_ASSERT(a < n && b < n, "material index {} or {} out of range ({})", a, b, n);
  laws_.push_back(std::move(law));
  lawOf_[a * n + b] = lawOf_[b * n + a] = static_cast<int>(laws_.size() - 1);
}

bool Simulation::hasInteraction(std::uint32_t a, std::uint32_t b) const { return interaction(a, b) != nullptr; }

const ContactLaw* Simulation::interaction(std::uint32_t a, std::uint32_t b) const {
  const int i = lawOf_[a * materials_.size() + b];
  return i < 0 ? nullptr : laws_[static_cast<std::size_t>(i)].get();
}

std::uint32_t Simulation::addSphere(const Vec3& position, double radius, std::uint32_t material, const Vec3& velocity,
                                    const Vec3& angularVelocity, bool fixed) {
  const double mass = 4.0 / 3.0 * kPi * radius * radius * radius * materials_[material].density;
  return addCluster({Vec3::Zero()}, {radius}, material, mass, Vec3::Constant(0.4 * mass * radius * radius), position,
                    Quat::Identity(), velocity, angularVelocity, fixed);
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
  bodyReach_.push_back(reach);
  for (std::size_t i = 0; i < local.size(); ++i) {
    spheres_.local.push_back(local[i]);
    spheres_.position.push_back(position + orientation * local[i]);
    spheres_.radius.push_back(radii[i]);
    spheres_.material.push_back(material);
    spheres_.body.push_back(body);
  }
  return body;
}

std::uint32_t Simulation::addPlane(const PlaneWall& wall) {
  return planeWalls_->add(wall);
}

const std::vector<PlaneWall>& Simulation::planes() const { return planeWalls_->walls(); }
const std::vector<Vec3>& Simulation::planeForces() const { return planeWalls_->forces(); }
void Simulation::setPlaneVelocity(std::uint32_t plane, const Vec3& velocity) {
  planeWalls_->setVelocity(plane, velocity);
}

std::uint32_t Simulation::addMesh(MeshWall wall) { return meshWalls_->add(std::move(wall)); }

void Simulation::setMeshState(std::uint32_t mesh, const std::vector<Vec3>& positions, const std::vector<Vec3>& velocities) {
  meshWalls_->setState(mesh, positions, velocities);
}

const std::vector<MeshWall>& Simulation::meshes() const { return meshWalls_->walls(); }

double Simulation::criticalTimeStep() const {
  double dt = std::numeric_limits<double>::infinity();
  const auto nm = materials_.size();
  for (std::size_t s = 0; s < spheres_.size(); ++s) {
    const double m = bodies_.mass[spheres_.body[s]];
    for (std::size_t other = 0; other < nm; ++other)
      if (const ContactLaw* law = interaction(spheres_.material[s], static_cast<std::uint32_t>(other)))
        dt = std::min(dt, law->criticalTimeStep(materials_[spheres_.material[s]], spheres_.radius[s], 0.5 * m));
  }
  return dt;
}

double Simulation::contactDuration(double approachSpeed) const {
  if (!(approachSpeed > 0.0)) return std::numeric_limits<double>::infinity();
  const auto nm = materials_.size();
  // The smallest radius and body mass of each material's free spheres, and which materials walls and
  // fixed bodies are made of: the partners a sphere can meet.
  std::vector<double> minRadius(nm, std::numeric_limits<double>::infinity()), minMass = minRadius;
  std::vector<std::uint8_t> wallMaterial(nm, 0);
  for (const auto& p : planes()) wallMaterial[p.material] = 1;
  for (const auto& m : meshes()) wallMaterial[m.material] = 1;
  for (std::size_t s = 0; s < spheres_.size(); ++s) {
    const auto b = spheres_.body[s], mat = spheres_.material[s];
    if (bodies_.fixed[b]) {
      wallMaterial[mat] = 1;
      continue;
    }
    minRadius[mat] = std::min(minRadius[mat], spheres_.radius[s]);
    minMass[mat] = std::min(minMass[mat], bodies_.mass[b]);
  }
  const auto freeBodies = std::count(bodies_.fixed.begin(), bodies_.fixed.end(), std::uint8_t{0});
  double duration = std::numeric_limits<double>::infinity();
  // One evaluation per distinct (material, radius, mass) would do; spheres of one size repeat it cheaply.
  double lastR = -1, lastM = -1;
  std::uint32_t lastMat = static_cast<std::uint32_t>(nm);
  for (std::size_t s = 0; s < spheres_.size(); ++s) {
    const auto b = spheres_.body[s], mat = spheres_.material[s];
    const double R = spheres_.radius[s], m = bodies_.mass[b];
    if (bodies_.fixed[b] || (R == lastR && m == lastM && mat == lastMat)) continue;
    lastR = R, lastM = m, lastMat = mat;
    for (std::size_t o = 0; o < nm; ++o) {
      const ContactLaw* law = interaction(mat, static_cast<std::uint32_t>(o));
      if (!law) continue;
      if (wallMaterial[o]) duration = std::min(duration, law->elasticImpact(R, m, approachSpeed).contactDuration);
      if (freeBodies > 1 && std::isfinite(minRadius[o])) {
        const double Rs = R * minRadius[o] / (R + minRadius[o]), ms = m * minMass[o] / (m + minMass[o]);
        duration = std::min(duration, law->elasticImpact(Rs, ms, approachSpeed).contactDuration);
      }
    }
  }
  return duration;
}

std::vector<std::pair<std::string, bool>> Simulation::physics() const {
  const bool friction = std::any_of(laws_.begin(), laws_.end(), [](const auto& l) { return l->friction() > 0.0; });
  return {{"rotation", rotation_},
          {"friction", friction},
          {"rolling_resistance", rolling_},
          {"sphere_pairs", pairsPossible_},
          {"plane_walls", !planeWalls_->empty()},
          {"mesh_walls", !meshWalls_->empty()},
          {"local_damping", settings_.localDamping > 0.0},
          {"cohesive_bonds", bonds_.created() > 0},
          {"lone_sphere_path", loneSpheres_}};
}

std::vector<double> Simulation::fragmentMasses() const {
  const auto& ever = bonds_.everBonded();
  if (ever.empty()) return {};
  // Union–find over bodies.
  std::vector<std::uint32_t> parent(bodies_.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const Bond& b : bonds_.bonds()) parent[find(spheres_.body[b.a])] = find(spheres_.body[b.b]);
  std::vector<double> mass(bodies_.size(), 0.0);
  std::vector<std::uint8_t> counted(bodies_.size(), 0);
  for (std::size_t s = 0; s < ever.size(); ++s) {
    const auto b = spheres_.body[s];
    if (!ever[s] || counted[b]) continue;
    counted[b] = 1;
    mass[find(b)] += bodies_.mass[b];
  }
  std::vector<double> out;
  for (double m : mass)
    if (m > 0.0) out.push_back(m);
  std::sort(out.begin(), out.end(), std::greater<>());
  return out;
}

bool Simulation::bondingLaws() const {
  return std::any_of(laws_.begin(), laws_.end(), [](const auto& l) { return l->bonding() != nullptr; });
}

BondSet::View Simulation::bondView() const {
  return {centres().data(),          spheres_.radius.data(),   spheres_.body.data(), bodies_.position.data(),
          bodies_.velocity.data(),   bodies_.angularVelocity.data(), spheres_.size()};
}

void Simulation::formBonds() {
  COSIM_ASSERT(initialized_, "Simulation::formBonds() before initialize()");
  if (positionsStale_) updateSpherePositions(true);
  // The touching pairs' shear springs, by (a, b): their bonds start from them.
  const ContactSet& ss = *sphereContacts_;
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
  rebuildContacts({true, false, false});  // the bonded pairs leave the contact candidates
}

std::string Simulation::shape() const {
  std::string meshes;
  for (const MeshWall& m : this->meshes()) meshes += fmt::format("{}{} ({} nodes, {} triangles)", meshes.empty() ? "" : ", ", m.name, m.nodes.size(), m.triangles.size());
  return fmt::format("{} bodies, {} spheres, {} plane walls, mesh walls [{}], {} materials, {} laws", bodies_.size(),
                     spheres_.size(), planes().size(), meshes, materials_.size(), laws_.size());
}

int Simulation::lawIndex(const ContactLaw* law) const {
  for (std::size_t i = 0; i < laws_.size(); ++i)
    if (laws_[i].get() == law) return static_cast<int>(i);
  return -1;
}

const ContactLaw* Simulation::law(int index) const {
  return index < 0 || static_cast<std::size_t>(index) >= laws_.size() ? nullptr : laws_[static_cast<std::size_t>(index)].get();
}

const BondingLaw* Simulation::bondingLaw(std::uint32_t s, std::uint32_t t, std::size_t materials) const {
  const int l = lawOf_[spheres_.material[s] * materials + spheres_.material[t]];
  return l < 0 ? nullptr : laws_[static_cast<std::size_t>(l)]->bonding();
}

void Simulation::createBonds(const BondSet::ShearOf& shearOf) {
  const std::size_t nm = materials_.size();
  double rmax = 0.0;
  for (double r : spheres_.radius) rmax = std::max(rmax, r);
  double reach = 0.0;
  for (const auto& law : laws_)
    if (const BondingLaw* b = law->bonding()) reach = std::max(reach, b->bondReach(rmax, rmax));
  if (reach == 0.0) {
    bonds_ = BondSet{};
    return;
  }
  auto lawOf = [&](std::uint32_t s, std::uint32_t t) { return bondingLaw(s, t, nm); };
  auto massOf = [&](std::uint32_t s, std::uint32_t t) {
    const auto a = spheres_.body[s], b = spheres_.body[t];
    return reduced(bodies_.mass[a], bodies_.mass[b], bodies_.fixed[a] != 0, bodies_.fixed[b] != 0);
  };
  bonds_.create(bondView(), lawOf, massOf, reach, shearOf);
}

std::vector<Simulation::NetworkLine> Simulation::contactNetwork() const {
  std::vector<NetworkLine> out;
  const ContactSet& pairs = *sphereContacts_;
  const auto& x = spheres().position;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (!(pairs.overlap[i] > 0.0)) continue;
    const auto t = laws_[static_cast<std::size_t>(pairs.law[i])]->normalTangent(pairs.effRadius[i], pairs.effMass[i],
                                                                             pairs.overlap[i]);
    out.push_back({x[pairs.a[i]], x[pairs.b[i]], t.force});
  }
  for (const auto& line : bonds_.lines()) out.push_back({x[line.a], x[line.b], line.normalForce});
  return out;
}

double Simulation::contactStableStep() const {
  const auto nb = bodies_.size();
  std::vector<double> k(nb, 0.0), c(nb, 0.0);
  auto add = [&](std::uint32_t body, double stiffness, double damping) {
    k[body] += stiffness;
    c[body] += damping;
  };
  const ContactSet& pairs = *sphereContacts_;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (!(pairs.overlap[i] > 0.0)) continue;
    const auto ba = spheres_.body[pairs.a[i]], bb = spheres_.body[pairs.b[i]];
    const auto t = laws_[static_cast<std::size_t>(pairs.law[i])]->normalTangent(pairs.effRadius[i], pairs.effMass[i],
                                                                             pairs.overlap[i]);
    // Row b of M^{-1/2} K M^{-1/2}: the diagonal k/m_b and the coupling k/√(m_a m_b), scaled back by m_b.
    const double ma = bodies_.mass[ba], mb = bodies_.mass[bb];
    const double couplingA = bodies_.fixed[bb] ? 1.0 : 1.0 + std::sqrt(ma / mb);
    const double couplingB = bodies_.fixed[ba] ? 1.0 : 1.0 + std::sqrt(mb / ma);
    add(ba, t.stiffness * couplingA, t.damping * couplingA);
    add(bb, t.stiffness * couplingB, t.damping * couplingB);
  }
  for (const Bond& bond : bonds_.bonds()) {  // as a touching pair, in tension too
    const auto ba = spheres_.body[bond.a], bb = spheres_.body[bond.b];
    const double ma = bodies_.mass[ba], mb = bodies_.mass[bb];
    const double couplingA = bodies_.fixed[bb] ? 1.0 : 1.0 + std::sqrt(ma / mb);
    const double couplingB = bodies_.fixed[ba] ? 1.0 : 1.0 + std::sqrt(mb / ma);
    add(ba, bond.kn * couplingA, bond.gammaN * couplingA);
    add(bb, bond.kn * couplingB, bond.gammaN * couplingB);
  }
  const ContactSet& walls = planeWalls_->contacts();
  for (std::size_t i = 0; i < walls.size(); ++i) {
    const ContactPoint& p = walls.point[i];
    if (!(p.overlap > 0.0)) continue;
    const auto t = laws_[static_cast<std::size_t>(walls.law[i])]->normalTangent(p.effRadius, p.effMass, p.overlap);
    add(spheres_.body[walls.a[i]], t.stiffness, t.damping);
  }
  const MeshContacts& mc = meshWalls_->contacts();
  for (std::size_t i = 0; i < mc.contacts.size(); ++i) {
    const ContactPoint& p = mc.points[i];
    if (!(p.overlap > 0.0)) continue;
    const auto t = laws_[static_cast<std::size_t>(mc.contacts[i].law)]->normalTangent(p.effRadius, p.effMass, p.overlap);
    add(spheres_.body[mc.contacts[i].sphere], t.stiffness, t.damping);
  }
  double dt = std::numeric_limits<double>::infinity();
  for (std::size_t b = 0; b < nb; ++b) {
    if (bodies_.fixed[b] || !(k[b] > 0.0)) continue;
    const double m = bodies_.mass[b], omega = std::sqrt(k[b] / m), zeta = c[b] / (2.0 * std::sqrt(k[b] * m));
    dt = std::min(dt, 2.0 / omega * (std::sqrt(1.0 + zeta * zeta) - zeta));
  }
  return dt;
}

std::vector<double> Simulation::planeContactStiffness() const { return planeWalls_->contactStiffness(laws_); }

double Simulation::approachSpeedEstimate() const {
  double first = 0.0, second = 0.0;
  auto consider = [&](double speed) {
    if (speed > first) second = first, first = speed;
    else second = std::max(second, speed);
  };
  for (std::size_t b = 0; b < bodies_.size(); ++b) consider(bodies_.velocity[b].norm());
  for (const auto& p : planes()) consider(p.velocity.norm());
  for (const auto& m : meshes()) consider(m.velocity.norm());
  const double g = settings_.gravity.norm();
  double height = 0.0;
  if (g > 0.0) {
    const Vec3 down = settings_.gravity / g;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    auto extend = [&](const Vec3& x) {
      const double h = -down.dot(x);
      lo = std::min(lo, h), hi = std::max(hi, h);
    };
    for (const auto& x : bodies_.position) extend(x);
    for (const auto& p : planes())
      if (std::abs(p.normal.normalized().dot(down)) > 1e-9) extend(p.point);  // a wall along g bounds no fall
    for (const auto& m : meshes())
      for (const auto& x : m.nodes) extend(x);
    height = hi - lo;
  }
  return first + second + std::sqrt(2.0 * g * height);
}

void Simulation::initialize() {
  if (settings_.skin <= 0.0) {
    const double rmin = spheres_.size() ? *std::min_element(spheres_.radius.begin(), spheres_.radius.end()) : 1.0;
    settings_.skin = 0.2 * rmin;
  }
  if (settings_.meshSkin <= 0.0) settings_.meshSkin = meshWalls_->automaticSkin(spheres_, settings_.skin);
  // Members of one rigid body never touch each other: a lone cluster has no sphere pairs to track.
  const bool oneBody = std::all_of(spheres_.body.begin(), spheres_.body.end(),
                                   [&](auto b) { return b == spheres_.body.front(); });
  pairsPossible_ = !oneBody;
  // A single sphere only starts rotating under friction; without it and without spin, skip rotation.
  rotation_ = false;
  for (const auto& w : bodies_.angularVelocity) rotation_ |= w.squaredNorm() > 0.0;
  for (auto c : bodies_.sphereCount) rotation_ |= c > 1;  // off-centre member contacts exert torque
  loneSpheres_ = true;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Vec3& I = bodies_.inertia[b];
    loneSpheres_ &= bodies_.sphereCount[b] == 1 && spheres_.local[bodies_.firstSphere[b]].squaredNorm() == 0.0 &&
                    I.x() == I.y() && I.y() == I.z();
  }
  integrator_->prepare(bodies_, loneSpheres_);
  rolling_ = false;
  for (const auto& law : laws_) rolling_ |= law->rollingFriction() > 0.0;
  for (const auto& law : laws_) rotation_ |= law->friction() > 0.0 || rolling_;
  sphereForce_.assign(spheres_.size(), Vec3::Zero());
  sphereTorque_.assign(spheres_.size(), Vec3::Zero());
  updateSpherePositions(true);
  if (settings_.bondAtStart) createBonds();
  rotation_ |= !bonds_.empty();  // a bond's shear force is off-centre
  rebuildContacts({true, true, true});
  computeForces();
  energy_ = EnergyLedger{};
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    if (bodies_.fixed[b]) continue;
    energy_.kinetic += 0.5 * bodies_.mass[b] * bodies_.velocity[b].squaredNorm() +
                       0.5 * bodies_.angularVelocity[b].dot(bodies_.angularMomentum[b]);
    energy_.potential -= bodies_.mass[b] * settings_.gravity.dot(bodies_.position[b]);
  }
  if (pairEnergySummed_) energy_.elastic = pairEnergy_[0];
  energy_.elastic += bonds_.elasticEnergy();
  for (const auto* forces : contactForces())
    if (forces != &sphereContacts_->force || !pairEnergySummed_)
      for (const auto& f : *forces) energy_.elastic += f.elasticEnergy;
  energy_.damping = energy_.friction = 0.0;  // the initial force pass dissipates nothing
  initialEnergy_ = energy_.total();
  initialApproach_ = approachSpeedEstimate();
  phaseSeconds_ = PhaseSeconds{};
  initialized_ = true;
}

StepContext Simulation::context() {
  return {settings_, laws_, lawOf_, materials_.size(), bodies_, spheres_, centres().data(),
          forceSums().data(), torqueSums().data(), loneSpheres_, rotation_, rolling_};
}

std::array<const std::vector<ContactForce>*, 3> Simulation::contactForces() const {
  return {&sphereContacts_->force, &planeWalls_->contacts().force, &meshWalls_->contacts().forces};
}

void Simulation::updateSpherePositions(bool all) {
  // One rotation matrix per body, then a matrix–vector product per member: a quaternion rotation per
  // sphere costs twice as much, and a 22,000-sphere cluster does this every step.
  const auto nb = static_cast<std::ptrdiff_t>(bodies_.size());
  bodyRotation_.resize(bodies_.size());
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
  const auto n = static_cast<std::ptrdiff_t>(all ? spheres_.size() : active_.size());
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (std::ptrdiff_t i = 0; i < n; ++i) place(all ? static_cast<std::uint32_t>(i) : active_[static_cast<std::size_t>(i)]);
  positionsStale_ = !all && active_.size() < spheres_.size();
}

const Spheres& Simulation::spheres() const {
  // Placing the inactive spheres changes no state, only a cache of it.
  if (positionsStale_) const_cast<Simulation*>(this)->updateSpherePositions(true);
  return spheres_;
}

Simulation::Rebuild Simulation::needsRebuild() const {
  // A member of a rigid body moved by its body's Δx plus at most chord(Δθ) · reach since a build.
  const auto nb = static_cast<std::ptrdiff_t>(bodies_.size());
  auto turned = [&](std::ptrdiff_t b, const Poses& at) {
    if (bodyReach_[b] == 0.0) return 0.0;
    const double c = std::min(1.0, std::abs(bodies_.orientation[b].dot(at.orientation[b])));
    return 2.0 * std::sqrt(std::max(0.0, 1.0 - c * c)) * bodyReach_[b];  // 2 sin(θ/2) reach
  };
  Rebuild what = loneSpheres_ ? needsRebuildLone() : Rebuild{};
  if (pairsPossible_ && !loneSpheres_) {
    // A pair's gap changes by at most |Δx_a − u| + |Δx_b − u| for any common shift u, so motion shared by
    // all (a falling sample) uses up no skin. u: the middle of the box of the bodies' displacements.
    Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (std::ptrdiff_t b = 0; b < nb; ++b) {
      const Vec3 d = bodies_.position[b] - atPairs_.position[b];
      lo = lo.cwiseMin(d);
      hi = hi.cwiseMax(d);
    }
    const Vec3 u = 0.5 * (lo + hi);
    // Bodies that did not turn (every lone sphere) compare squared lengths: one square root at the end
    // instead of two per body, and the same maximum (the square root is monotonic and correctly rounded).
    double relative = 0.0, absolute = 0.0, relative2 = 0.0, absolute2 = 0.0;
#pragma omp parallel for schedule(static) reduction(max : relative, absolute, relative2, absolute2) if (nb > kParallelMin)
    for (std::ptrdiff_t b = 0; b < nb; ++b) {
      const Vec3 d = bodies_.position[b] - atPairs_.position[b];
      const double r = turned(b, atPairs_);
      if (r == 0.0) {
        relative2 = std::max(relative2, (d - u).squaredNorm());
        absolute2 = std::max(absolute2, d.squaredNorm());
      } else {
        relative = std::max(relative, (d - u).norm() + r);
        absolute = std::max(absolute, d.norm() + r);
      }
    }
    relative = std::max(relative, std::sqrt(relative2));
    absolute = std::max(absolute, std::sqrt(absolute2));
    what.pairs = 2.0 * std::min(relative, absolute) > settings_.skin;
  }
  auto movedSince = [&](const Poses& at) {
    double moved = 0.0, moved2 = 0.0;  // squared, as above, for bodies that did not turn
#pragma omp parallel for schedule(static) reduction(max : moved, moved2) if (nb > kParallelMin)
    for (std::ptrdiff_t b = 0; b < nb; ++b) {
      const Vec3 d = bodies_.position[b] - at.position[b];
      const double r = turned(b, at);
      if (r == 0.0) moved2 = std::max(moved2, d.squaredNorm());
      else moved = std::max(moved, d.norm() + r);
    }
    return std::max(moved, std::sqrt(moved2));
  };
  // A sphere–wall candidate stays valid while both sides together moved less than the skin (a point of a
  // triangle moves no more than its farthest node).
  if (!planeWalls_->empty() && !loneSpheres_) {
    what.planes = movedSince(atPlanes_) + planesMoved() > settings_.skin;
  }
  if (!meshWalls_->empty()) {
    const std::vector<MeshWall>& meshes = this->meshes();
    double maxNode = 0.0;
    for (std::size_t m = 0; m < meshes.size(); ++m)
      for (std::size_t n = 0; n < meshes[m].nodes.size(); ++n)
        maxNode = std::max(maxNode, (meshes[m].nodes[n] - meshNodesAtBuild_[m][n]).squaredNorm());
    what.mesh = movedSince(atMesh_) + std::sqrt(maxNode) > settings_.meshSkin;
  }
  return what;
}

Simulation::Rebuild Simulation::needsRebuildLone() const {
  // The pair and plane tests of needsRebuild() for bodies that never turn a member: the same tests on
  // squared lengths. One pass finds the box of the displacements and the largest displacement since
  // each build; the second, for the displacements relative to the box centre, runs only when the
  // absolute ones alone call for a pair rebuild (the relative ones can only avoid it): a settled
  // sample skips it.
  const auto nb = static_cast<std::ptrdiff_t>(bodies_.size());
  const Vec3* x = bodies_.position.data();
  const Vec3* atPairs = atPairs_.position.data();
  const bool pairs = pairsPossible_, planes = !planeWalls_->empty();
  const Vec3* atPlanes = planes ? atPlanes_.position.data() : nullptr;
  const int nt = nb > kParallelMin ? omp_get_max_threads() : 1;
  std::vector<Displacements> partial(static_cast<std::size_t>(nt));
  detail::forEachPart(nt, [&](std::size_t part) {
    const auto t = static_cast<std::ptrdiff_t>(part);
    const std::ptrdiff_t chunk = (nb + nt - 1) / nt, b1 = std::min(nb, (t + 1) * chunk);
    std::ptrdiff_t b0 = std::min(nb, t * chunk);
    Displacements& d = partial[part];
#if defined(__x86_64__) && defined(__GNUC__)
    if (detail::useAvx2()) b0 = displacementsAvx2(x, atPairs, atPlanes, b0, b1, d);
#endif
    displacementsScalar(x, atPairs, atPlanes, b0, b1, d);
  });
  Displacements d;
  for (const Displacements& p : partial) {
    for (int c = 0; c < 3; ++c) d.lo[c] = std::min(d.lo[c], p.lo[c]), d.hi[c] = std::max(d.hi[c], p.hi[c]);
    d.absolute2 = std::max(d.absolute2, p.absolute2), d.plane2 = std::max(d.plane2, p.plane2);
  }
  Rebuild what;
  what.planes = planes && std::sqrt(d.plane2) + planesMoved() > settings_.skin;
  if (!pairs || 2.0 * std::sqrt(d.absolute2) <= settings_.skin) return what;
  const Vec3 u = 0.5 * (Vec3(d.lo[0], d.lo[1], d.lo[2]) + Vec3(d.hi[0], d.hi[1], d.hi[2]));
  double relative2 = 0.0;
#pragma omp parallel for schedule(static) reduction(max : relative2) if (nb > kParallelMin)
  for (std::ptrdiff_t b = 0; b < nb; ++b) relative2 = std::max(relative2, (x[b] - atPairs[b] - u).squaredNorm());
  what.pairs = 2.0 * std::min(std::sqrt(relative2), std::sqrt(d.absolute2)) > settings_.skin;
  return what;
}

double Simulation::planesMoved() const {
  double moved = 0.0;
  for (std::size_t w = 0; w < planes().size(); ++w)
    moved = std::max(moved, (planes()[w].point - planePointsAtBuild_[w]).norm());
  return moved;
}

void Simulation::keepPoses(Poses& at) const {
  // Into the arrays of the last build: no allocation. Lone spheres never turn a member (bodyReach_ is
  // 0): the rebuild tests read no orientation.
  at.position.resize(bodies_.size());
  const auto nb = static_cast<std::ptrdiff_t>(bodies_.size());
#pragma omp parallel for schedule(static) if (nb > kParallelMin)
  for (std::ptrdiff_t b = 0; b < nb; ++b) at.position[b] = bodies_.position[b];
  if (loneSpheres_)
    at.orientation.clear();
  else
    at.orientation = bodies_.orientation;
}

void Simulation::rebuildContacts(Rebuild what) {
  ++rebuilds_;
  if (positionsStale_) updateSpherePositions(true);
  if (what.pairs) {
    rebuildPairCandidates();
    keepPoses(atPairs_);
  }
  if (what.planes) {
    planeWalls_->rebuildCandidates(context());
    planePointsAtBuild_.clear();
    for (const auto& p : planes()) planePointsAtBuild_.push_back(p.point);
    keepPoses(atPlanes_);
  }
  if (what.pairs || what.planes) refsStale_ = true;  // built when bodyContacts() asks
  if (what.mesh) {
    meshWalls_->rebuildCandidates(context());
    meshNodesAtBuild_.clear();
    for (const auto& w : meshes()) meshNodesAtBuild_.push_back(w.nodes);
    keepPoses(atMesh_);
  }
  // The active spheres: those in a candidate of any kind, and per body its run of them. Only these get
  // forces computed; the others' stay zero.
  const std::size_t ns = spheres_.size();
  const auto count = static_cast<std::ptrdiff_t>(ns);
  const int nt = count > kParallelMin ? omp_get_max_threads() : 1;
  Vec3* force = forceSums().data();
  Vec3* torque = torqueSums().data();
  auto& in = scratch_->inCandidate;
  in.resize(ns);
  auto& threadCount = scratch_->threadCount;
  threadCount.assign(static_cast<std::size_t>(nt) + 1, 0);
  const ContactSet& pairs = *sphereContacts_;
  const ContactSet& walls = planeWalls_->contacts();
  const auto np = static_cast<std::ptrdiff_t>(pairs.size()), nw = static_cast<std::ptrdiff_t>(walls.size());
  // Lone spheres: sphere s is body s, so its run starts after the active spheres before it.
  const bool lone = loneSpheres_;
  if (lone) activeStart_.resize(ns + 1);
#pragma omp parallel num_threads(nt) if (nt > 1)
  {
    const auto t = static_cast<std::size_t>(omp_get_thread_num());
#pragma omp for schedule(static)
    for (std::ptrdiff_t s = 0; s < count; ++s) in[s] = 0, force[s].setZero(), torque[s].setZero();
    // Several threads may mark one sphere, all with the same value.
    auto mark = [&](std::uint32_t s) { std::atomic_ref<unsigned char>(in[s]).store(1, std::memory_order_relaxed); };
#pragma omp for schedule(static)
    for (std::ptrdiff_t k = 0; k < np; ++k) mark(pairs.a[k]), mark(pairs.b[k]);
#pragma omp for schedule(static)
    for (std::ptrdiff_t k = 0; k < nw; ++k) mark(walls.a[k]);
#pragma omp single
    {
      for (const auto& c : meshWalls_->contacts().candidates) mark(c.sphere);
      bonds_.forEachBondedSphere(mark);
    }
    // The active spheres in order: each thread counts its run of spheres, then writes them after the
    // runs before it (the same static split in both loops).
    std::uint32_t mine = 0;
#pragma omp for schedule(static)
    for (std::ptrdiff_t s = 0; s < count; ++s) mine += in[s];
    threadCount[t + 1] = mine;
#pragma omp barrier
#pragma omp single
    {
      std::partial_sum(threadCount.begin(), threadCount.end(), threadCount.begin());
      active_.resize(threadCount.back());
    }
    std::uint32_t next = threadCount[t];
#pragma omp for schedule(static)
    for (std::ptrdiff_t s = 0; s < count; ++s) {
      if (lone) activeStart_[s] = next;
      if (in[s]) active_[next++] = static_cast<std::uint32_t>(s);
    }
  }
  if (lone) {
    activeStart_[ns] = static_cast<std::uint32_t>(active_.size());
    return;
  }
  activeStart_.assign(bodies_.size() + 1, 0);
  for (auto s : active_) ++activeStart_[spheres_.body[s] + 1];
  std::partial_sum(activeStart_.begin(), activeStart_.end(), activeStart_.begin());
}

void Simulation::rebuildPairCandidates() {
  const std::size_t ns = spheres_.size();
  const double skin = settings_.skin;

  // Sphere–sphere: linked cells of edge ≥ 2 r_max + skin, so neighbours are within the 27 cells around.
  std::vector<Triple>& pairs = scratch_->joined;
  pairs.clear();
  if (ns > 1 && pairsPossible_) {
    double lx = kInf, ly = kInf, lz = kInf, hx = -kInf, hy = -kInf, hz = -kInf;
    const Vec3* position = spheres_.position.data();
    const auto count = static_cast<std::ptrdiff_t>(ns);
    // clang-format off
#pragma omp parallel for schedule(static) reduction(min : lx, ly, lz) reduction(max : hx, hy, hz) if (count > kParallelMin)
    // clang-format on
    for (std::ptrdiff_t s = 0; s < count; ++s) {
      lx = std::min(lx, position[s].x()), ly = std::min(ly, position[s].y()), lz = std::min(lz, position[s].z());
      hx = std::max(hx, position[s].x()), hy = std::max(hy, position[s].y()), hz = std::max(hz, position[s].z());
    }
    common::Aabb box;
    box.expand(Vec3(lx, ly, lz));
    box.expand(Vec3(hx, hy, hz));
    const double rmax = *std::max_element(spheres_.radius.begin(), spheres_.radius.end());
    double cell = 2.0 * rmax + skin;
    const Vec3 extent = box.extent();
    // Keep the grid at most ~2 cells per sphere so sparse scenes do not allocate huge grids.
    while ((extent / cell).array().floor().matrix().prod() > 2.0 * static_cast<double>(ns) + 27) cell *= 1.5;
    Eigen::Array3i dims = ((extent / cell).array().floor() + 1).cast<int>();
    // A layer of empty cells around the grid: the 27 neighbours of any cell are at fixed index offsets,
    // with no bounds to check.
    const Eigen::Array3i padded = dims + 2;
    auto cellOf = [&](const Vec3& p) -> std::uint32_t {
      const Eigen::Array3i c = ((p - box.min) / cell).array().floor().cast<int>().min(dims - 1) + 1;
      return static_cast<std::uint32_t>((c.z() * padded.y() + c.y()) * padded.x() + c.x());
    };
    // The 27 cells around as 9 runs of three cells along x, which are consecutive in the grid and so
    // their spheres in `order`: run r holds cells row[r] .. row[r] + 2.
    std::array<std::ptrdiff_t, 9> row{};
    for (int dz = -1, n = 0; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy) row[n++] = (dz * padded.y() + dy) * padded.x() - 1;
    const std::size_t ncells = static_cast<std::size_t>(padded.prod());
    std::vector<std::uint32_t>& start = scratch_->cellStart;
    std::vector<std::uint32_t>& cellIndex = scratch_->cellIndex;
    start.assign(ncells + 1, 0);
    cellIndex.resize(ns);
    CellOrdered& sorted = scratch_->cellOrdered;
    sorted.resize(ns);
    std::uint32_t* order = sorted.index.data();
#pragma omp parallel for schedule(static) if (count > kParallelMin)
    for (std::ptrdiff_t s = 0; s < count; ++s) cellIndex[s] = cellOf(position[s]);
    for (std::size_t s = 0; s < ns; ++s) ++start[cellIndex[s] + 1];
    std::partial_sum(start.begin(), start.end(), start.begin());
    {
      std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
      for (std::size_t s = 0; s < ns; ++s) order[fill[cellIndex[s]]++] = static_cast<std::uint32_t>(s);
    }
    // Centres and radii in cell order: a cell's spheres are read one after the other.
#pragma omp parallel for schedule(static) if (count > kParallelMin)
    for (std::ptrdiff_t k = 0; k < count; ++k) {
      const Vec3& x = position[order[k]];
      sorted.x[k] = x.x(), sorted.y[k] = x.y(), sorted.z[k] = x.z(), sorted.r[k] = spheres_.radius[order[k]];
    }
    [[maybe_unused]] const bool avx2 = detail::useAvx2();
    const bool bonded = !bonds_.empty();
    // Each sphere's partners sorted as found (a handful), the threads' runs of spheres joined in order:
    // the list comes out sorted by (a, b), so with one law it needs no global sort.
    auto& local = scratch_->local;
    local.resize(static_cast<std::size_t>(omp_get_max_threads()));
    for (auto& l : local) l.clear();
#pragma omp parallel if (static_cast<std::ptrdiff_t>(ns) > kParallelMin)
    {
      const auto thread = static_cast<std::size_t>(omp_get_thread_num());
      auto& mine = local[thread];
      std::vector<std::uint32_t> found;  // sphere i's partners j > i within reach
#pragma omp for schedule(static)
      for (std::ptrdiff_t si = 0; si < static_cast<std::ptrdiff_t>(ns); ++si) {
        const auto i = static_cast<std::uint32_t>(si);
        const Vec3 xi = spheres_.position[i];
        const double ri = spheres_.radius[i];
        std::uint32_t k0[9], k1[9];  // the runs of spheres around, in cell order
        std::size_t around = 0;
        for (int r = 0; r < 9; ++r) {
          const auto ci = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(cellIndex[i]) + row[r]);
          k0[r] = start[ci], k1[r] = start[ci + 3];
          around += k1[r] - k0[r];
        }
        if (found.size() < around + 4) found.resize(around + 4);
        std::uint32_t* out = found.data();
        std::size_t n = 0;
#if defined(__x86_64__) && defined(__GNUC__)
        if (avx2)
          n = partnersAvx2(sorted, k0, k1, i, xi, ri, skin, out);
        else
#endif
          for (int r = 0; r < 9; ++r) n = partnersScalar(sorted, k0[r], k1[r], i, xi, ri, skin, out, n);
        std::sort(out, out + n);
        for (std::size_t p = 0; p < n; ++p) {
          const std::uint32_t j = out[p];
          // After the distance: body[j] is a load from anywhere, and lone spheres need no test.
          if (!loneSpheres_ && spheres_.body[i] == spheres_.body[j]) continue;
          if (bonded && bonds_.bonded(i, j)) continue;  // the bond acts instead, until it breaks
          const int law = lawOf_[spheres_.material[i] * materials_.size() + spheres_.material[j]];
          if (law >= 0) mine.emplace_back(law, i, j);
        }
      }
      joinInOrder(local, thread, pairs);
    }
    // Several laws: order by law, keeping (a, b) order within each (ContactSet::assign wants (law, a, b)).
    // Often all pairs share one law (the others are with walls): then they are in order already.
    auto byLaw = [](const Triple& x, const Triple& y) { return std::get<0>(x) < std::get<0>(y); };
    if (laws_.size() > 1 && !std::is_sorted(pairs.begin(), pairs.end(), byLaw))
      std::stable_sort(pairs.begin(), pairs.end(), byLaw);
  }
  sphereContacts_->assign(pairs, laws_.size(), scratch_->pairs, rolling_);
  // R* and m* are fixed for a pair: set once here, not per step in computeGeometry.
  ContactSet& ss = *sphereContacts_;
  ss.effRadius.resize(ss.size());  // the first build: assign() found none to keep
  ss.effMass.resize(ss.size());
  // δ of the last pass where it touched (its history's), else 0: the pass reads it to find the pairs that
  // just opened (SpherePairView::overlap), then writes every candidate's.
  ss.overlap.resize(ss.size());
  const auto nss = static_cast<std::ptrdiff_t>(ss.size());
#pragma omp parallel for schedule(static) if (nss > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nss; ++k) {
    ss.overlap[k] = ss.history[k].lastOverlap;
    if (ss.effRadius[k] > 0.0) continue;  // a surviving pair's, kept by assign()
    const auto i = ss.a[k], j = ss.b[k], bi = spheres_.body[i], bj = spheres_.body[j];
    const double ri = spheres_.radius[i], rj = spheres_.radius[j];
    ss.effRadius[k] = ri * rj / (ri + rj);
    ss.effMass[k] = reduced(bodies_.mass[bi], bodies_.mass[bj], bodies_.fixed[bi], bodies_.fixed[bj]);
  }
  if (rolling_)  // the rolling pass reads them from the contact points
    for (std::size_t k = 0; k < ss.size(); ++k) ss.point[k].effRadius = ss.effRadius[k], ss.point[k].effMass = ss.effMass[k];
}

void Simulation::rebuildReferences() const {
  refsStale_ = false;
  const std::size_t ns = spheres_.size();
  // Sphere → contact references, in a fixed order (sphere contacts first, then walls).
  refStart_.assign(ns + 1, 0);
  for (auto s : sphereContacts_->a) ++refStart_[s + 1];
  for (auto s : sphereContacts_->b) ++refStart_[s + 1];
  const ContactSet& walls = planeWalls_->contacts();
  for (auto s : walls.a) ++refStart_[s + 1];
  std::partial_sum(refStart_.begin(), refStart_.end(), refStart_.begin());
  refs_.resize(refStart_.back());
  std::vector<std::uint32_t> fill(refStart_.begin(), refStart_.end() - 1);
  for (std::uint32_t k = 0; k < sphereContacts_->size(); ++k) {
    refs_[fill[sphereContacts_->a[k]]++] = {k, 0, +1};
    refs_[fill[sphereContacts_->b[k]]++] = {k, 0, -1};
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
  const double dt = settings_.dt;
  auto inertia = [&](std::uint32_t s) {
    const double r = spheres_.radius[s];
    return 0.4 * bodies_.mass[spheres_.body[s]] * r * r;
  };
  const ContactSet& ss = *sphereContacts_;
  for (std::size_t k = 0; k < ss.size(); ++k) {
    const double muR = laws_[static_cast<std::size_t>(ss.law[k])]->rollingFriction();
    const ContactPoint& p = ss.point[k];
    if (muR == 0.0 || p.overlap <= 0.0) continue;
    const auto a = ss.a[k], b = ss.b[k], ba = spheres_.body[a], bb = spheres_.body[b];
    const double ia = inertia(a), ib = inertia(b);
    const double eff = reduced(ia, ib, bodies_.fixed[ba], bodies_.fixed[bb]);
    const Vec3 m = detail::rollingTorque(p.normal, bodies_.angularVelocity[ba] - bodies_.angularVelocity[bb], p.effRadius,
                                         eff, muR, sphereContacts_->force[k].normalForce, dt, sphereContacts_->force[k]);
    torqueSums()[a] += m;
    torqueSums()[b] -= m;
  }
  planeWalls_->applyRollingResistance(context());
  meshWalls_->applyRollingResistance(context());
}

void Simulation::computeForces() {
  // The contacts add their forces to the spheres in contact order (sphere pairs, then walls, then meshes;
  // for several threads see BatchLaw::spherePairs).
  PhaseSeconds& phase = phaseSeconds_;
  Stopwatch watch;
  // The bonds before the contacts: a pair whose bond breaks in this step is a contact candidate in it.
  // The step's sums are renewed even when every bond has broken. What breaking releases is booked here:
  // the initial pass's, if any, is then before the initial total (initialize() resets the ledger).
  if (bonds_.created() > 0) {
    const std::size_t broke = bonds_.compute(bondView(), settings_.dt);
    energy_.bondFracture += bonds_.releasedEnergy();
    if (broke > 0) rebuildContacts({true, false, false});
  }
  watch.lap(phase.sphereContacts);
  computeGeometry();
  watch.lap(phase.wallContacts);
  threadSeconds_.resize(static_cast<std::size_t>(std::max(1, omp_get_max_threads())));
  Vec3* force = forceSums().data();
  Vec3* torque = torqueSums().data();
  const auto na = static_cast<std::ptrdiff_t>(active_.size());
  if (const auto ns = static_cast<std::ptrdiff_t>(spheres_.size()); 2 * na >= ns) {
    // Most spheres touch something (a settled sample): all of them, in order, is less work than the
    // active ones through their indices (the others' sums are zero already).
#pragma omp parallel for schedule(static) if (ns > kParallelMin)
    for (std::ptrdiff_t i = 0; i < ns; ++i) force[i].setZero(), torque[i].setZero();
  } else {
#pragma omp parallel for schedule(static) if (na > kParallelMin)
    for (std::ptrdiff_t i = 0; i < na; ++i) {
      force[active_[static_cast<std::size_t>(i)]].setZero();
      torque[active_[static_cast<std::size_t>(i)]].setZero();
    }
  }
  ContactSet& ss = *sphereContacts_;
  // Without rolling resistance nothing reads the pairs' contact points or forces after the pass
  // (bodyContacts takes the bodies' sums): not stored, 32 to 136 bytes per touching pair and step. The
  // energies are summed in the pass unless rolling resistance adds to them after.
  const SpherePairView pairs{ss.a.data(), ss.b.data(), ss.effRadius.data(), ss.effMass.data(), ss.overlap.data(),
                             ss.point.data(), rolling_, ss.history.data(), rolling_ ? ss.force.data() : nullptr,
                             centres().data(), spheres_.radius.data(), spheres_.body.data(),
                             bodies_.position.data(), bodies_.velocity.data(), bodies_.angularVelocity.data(),
                             loneSpheres_, force, rotation_ ? torque : nullptr,
                             rolling_ ? nullptr : pairEnergy_.data(),
                             loneSpheres_ && spheres_.size() > kPrefetchSpheres, threadSeconds_.data()};
  pairEnergy_ = {};
  pairEnergySummed_ = pairs.energy != nullptr;
  watch.lap(phase.other);
  for (std::size_t l = 0; l < laws_.size(); ++l) {
    const auto [begin, end] = ss.ranges[l];
    if (begin == end) continue;
    std::fill(threadSeconds_.begin(), threadSeconds_.end(), 0.0);
    laws_[l]->computeSpherePairs(pairs, begin, end, settings_.dt);
    const double slowest = *std::max_element(threadSeconds_.begin(), threadSeconds_.end());
    const double mean = std::accumulate(threadSeconds_.begin(), threadSeconds_.end(), 0.0) /
                        static_cast<double>(std::count_if(threadSeconds_.begin(), threadSeconds_.end(),
                                                          [](double t) { return t > 0.0; }));
    if (slowest > 0.0) phase.sphereContactsWait += slowest - mean;
  }
  if (!bonds_.empty()) bonds_.scatter(bondView(), force, rotation_ ? torque : nullptr);
  watch.lap(phase.sphereContacts);
  planeWalls_->computeContacts(context());
  meshWalls_->computeForces(context());
  watch.lap(phase.wallContacts);
  if (rolling_) applyRollingResistance();
  const auto nb = static_cast<std::ptrdiff_t>(loneSpheres_ ? 0 : bodies_.size());  // lone: in integrate()
#pragma omp parallel for schedule(static) if (nb > kParallelMin)
  for (std::ptrdiff_t b = 0; b < nb; ++b) {
    Vec3 f = Vec3::Zero(), t = Vec3::Zero();
    for (std::uint32_t i = activeStart_[b]; i < activeStart_[b + 1]; ++i) {
      const std::uint32_t s = active_[i];
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

void Simulation::step() {
  COSIM_ASSERT(initialized_, "Simulation::step() before initialize()");
  PhaseSeconds& phase = phaseSeconds_;
  Stopwatch watch;
  if (integrator_->steps() > 0) {
    if (!loneSpheres_) updateSpherePositions(false);  // lone spheres' centres are read from their bodies
    if (const Rebuild what = needsRebuild(); what.pairs || what.planes || what.mesh) rebuildContacts(what);
    watch.lap(phase.neighbour);
    computeForces();
    watch.restart();
  }
  std::array<double, 3> sums{};  // elastic, damping, friction
  if (pairEnergySummed_) sums = pairEnergy_;
  for (const auto* forces : contactForces()) {
    const bool pairs = forces == &sphereContacts_->force;
    if (pairs && pairEnergySummed_) continue;
    // Open sphere pairs add nothing; their stored forces are stale after steps that did not store them.
    const double* overlap = pairs ? sphereContacts_->overlap.data() : nullptr;
    const ContactForce* f = forces->data();
    orderedSum(static_cast<std::ptrdiff_t>(forces->size()), sums, [&](std::ptrdiff_t i, std::array<double, 3>& sum) {
      if (overlap && overlap[i] <= 0.0) return;
      sum[0] += f[i].elasticEnergy;
      sum[1] += f[i].dampingEnergy;
      sum[2] += f[i].frictionEnergy;
    });
  }
  energy_.elastic = sums[0] + bonds_.elasticEnergy();
  energy_.damping += sums[1] + bonds_.dampingEnergy();
  energy_.friction += sums[2];
  watch.lap(phase.other);
  integrate();
  watch.lap(phase.integrate);
  // A free body's non-finite position or velocity makes the kinetic or potential sum non-finite (0·inf
  // is NaN too); only then look for it. Fixed bodies move at their prescribed, finite velocities.
  if (!std::isfinite(energy_.kinetic + energy_.potential))
    for (std::size_t b = 0; b < bodies_.size(); ++b)
      if (!std::isfinite(bodies_.position[b].squaredNorm()) || !std::isfinite(bodies_.velocity[b].squaredNorm())) {
        const double critical = criticalTimeStep(), safe = safeTimeStep(initialApproach_);
        const bool externalWalls = std::any_of(meshes().begin(), meshes().end(),
                                               [](const MeshWall& w) { return w.motion == MeshWall::Motion::kExternal; });
        const bool tooLarge = settings_.dt > safe;
        const std::string evidence = fmt::format(
            "its position or velocity is not finite after step {}; dt = {:.4g} s is {:.3g} × the critical step {:.4g} s",
            steps(), settings_.dt, settings_.dt / critical, critical);
        const std::string fix =
            tooLarge ? fmt::format("dt = {:.3g} s (min of dt_safety {} × critical and the contact duration at {:.3g} m/s "
                                   "over steps_per_contact {})",
                                   safe, settings_.dtSafety, initialApproach_, settings_.stepsPerContact)
            : externalWalls
                ? "the time step is safe, so the input diverged: a wall driven from outside moved wildly (a coupling "
                  "window that did not converge: lower coupling.time_window or tighten its tolerance; see the coupler's "
                  "warnings)"
                : "the time step is safe: check the prescribed motions and forces";
        throw common::InstabilityError({"non-finite state", fmt::format("body {}", b), time(), evidence, fix});
      }
}

BodyContacts Simulation::bodyContacts(std::uint32_t body) const {
  if (refsStale_) rebuildReferences();
  BodyContacts out;
  for (std::uint32_t i = activeStart_[body]; i < activeStart_[body + 1]; ++i)
    for (std::uint32_t r = refStart_[active_[i]]; r < refStart_[active_[i] + 1]; ++r) {
      const Ref& ref = refs_[r];
      const ContactSet& set = ref.wall ? planeWalls_->contacts() : *sphereContacts_;
      const double overlap = ref.wall ? set.point[ref.index].overlap : pairOverlap(ref.index);
      if (overlap > out.maxOverlap) {
        out.maxOverlap = overlap;
        out.law = laws_[static_cast<std::size_t>(set.law[ref.index])].get();
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
      out.law = laws_[static_cast<std::size_t>(mc.contacts[i].law)].get();
      out.effRadius = p.effRadius;
      out.effMass = p.effMass;
    }
    ++out.count;
  }
  out.force = bodies_.force[body];  // the sum of its contact forces (sphere pairs may not store theirs)
  return out;
}

std::tuple<std::uint32_t, std::uint32_t, double> Simulation::largestSphereOverlap() const {
  std::tuple<std::uint32_t, std::uint32_t, double> worst{0, 0, -std::numeric_limits<double>::infinity()};
  const ContactSet& ss = *sphereContacts_;
  for (std::size_t k = 0; k < ss.size(); ++k)
    if (const double overlap = pairOverlap(k); overlap > std::get<2>(worst)) worst = {ss.a[k], ss.b[k], overlap};
  return worst;
}

Simulation::ContactCounts Simulation::contactCounts() const {
  ContactCounts c;
  const ContactSet& ss = *sphereContacts_;
  c.pairCandidates = static_cast<std::int64_t>(ss.size());
  for (std::size_t k = 0; k < ss.size(); ++k) c.pairs += ss.overlap[k] > 0.0;
  for (const ContactPoint& p : planeWalls_->contacts().point) c.walls += p.overlap > 0.0;
  c.walls += static_cast<std::int64_t>(meshWalls_->contacts().contacts.size());
  return c;
}

double Simulation::pairOverlap(std::size_t k) const {
  const ContactSet& ss = *sphereContacts_;
  const double stored = ss.overlap[k];
  if (stored > 0.0) return stored;
  // Open: −d² is stored (SpherePairView::overlap).
  return std::min(spheres_.radius[ss.a[k]] + spheres_.radius[ss.b[k]] - std::sqrt(-stored), 0.0);
}

Vec3 Simulation::totalAngularMomentum() const {
  Vec3 L = Vec3::Zero();
  for (std::size_t b = 0; b < bodies_.size(); ++b)
    if (!bodies_.fixed[b]) L += bodies_.mass[b] * bodies_.position[b].cross(bodies_.velocity[b]) + bodies_.angularMomentum[b];
  return L;
}

Vec3 Simulation::bodyVelocity(std::uint32_t body) const {
  const double m = bodies_.mass[body];
  // v(t) = v(t − dt/2) + a(t) dt/2 needs the next force; the last acceleration instead is O(dt²) off.
  // Before the first step the stored velocity is the scene's v(0) itself.
  if (bodies_.fixed[body] || integrator_->steps() == 0) return bodies_.velocity[body];
  return bodies_.velocity[body] + 0.5 * settings_.dt * (bodies_.force[body] / m + settings_.gravity);
}

}  // namespace dem
