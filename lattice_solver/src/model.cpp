#include "lattice/model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include <omp.h>

#include <Eigen/Geometry>
#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/state_archive.hpp"
#include "stiffness.hpp"

namespace lattice {

namespace {

// Interleaves the low 21 bits of x with two zero bits between each (Morton code helper).
std::uint64_t spread(std::uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}


}  // namespace

Model::Model(const Specimen& sp, std::unique_ptr<RodLaw> law, const std::array<PhaseProperties, kPhaseCount>& phases,
             const RodSection& section, const Supports& supports, Operator op)
    : box_(sp.box), nodes_(sp.nodes), rods_(sp.rods), phases_(sp.phases), law_(std::move(law)), op_(op), props_(phases),
      section_(section), supports_(supports) {
  COSIM_ASSERT(phases_.size() == rods_.size(), "{} phases for {} rods", phases_.size(), rods_.size());
  const std::size_t N = nodes_.size();
  const int ax = supports_.axis;
  height_ = sp.box.size[ax];
  area_ = supports_.loadedArea > 0 ? supports_.loadedArea : sp.box.volume() / height_;
  length_.resize(rods_.size());
  axis_.resize(rods_.size());
  springs_.resize(rods_.size());
  for (std::size_t r = 0; r < rods_.size(); ++r) {
    const Vec3 d = nodes_[rods_[r][1]] - nodes_[rods_[r][0]];
    length_[r] = d.norm();
    axis_[r] = d / length_[r];
    springs_[r] = law_->springs(length_[r], props_[static_cast<std::size_t>(phases_[r])].stiffness, section_);
  }

  nodeRodStart_.assign(N + 1, 0);
  for (const auto& rod : rods_)
    for (auto n : rod) ++nodeRodStart_[n + 1];
  std::partial_sum(nodeRodStart_.begin(), nodeRodStart_.end(), nodeRodStart_.begin());
  nodeRods_.resize(nodeRodStart_.back());
  {
    std::vector<std::uint32_t> fill(nodeRodStart_.begin(), nodeRodStart_.end() - 1);
    for (std::uint32_t r = 0; r < rods_.size(); ++r)
      for (auto n : rods_[r]) nodeRods_[fill[n]++] = r;
  }

  // Supports.
  constrained_.assign(6 * N, 0);
  prescribed_.assign(6 * N, 0.0);
  movingFace_.assign(N, 0);
  const double lo = sp.box.origin[ax], hi = lo + height_, tol = 1e-9 * height_;
  if (!supports_.coupled.empty()) {
    coupledSupports(sp);
  } else {
    std::vector<std::uint32_t> face[2];
    for (std::uint32_t n = 0; n < N; ++n) {
      if (nodeRodStart_[n + 1] == nodeRodStart_[n]) continue;
      if (std::abs(nodes_[n][ax] - lo) <= tol) face[0].push_back(n);
      if (std::abs(nodes_[n][ax] - hi) <= tol) face[1].push_back(n);
    }
    if (face[0].empty() || face[1].empty())
      throw std::invalid_argument("the specimen has no rod ends on one of its loaded faces");
    const int l1 = (ax + 1) % 3, l2 = (ax + 2) % 3;
    for (int f = 0; f < 2; ++f) {
      for (auto n : face[f]) {
        constrained_[6 * n + static_cast<std::size_t>(ax)] = 1;
        if (f == 1) {
          prescribed_[6 * n + static_cast<std::size_t>(ax)] = height_;
          movingFace_[n] = 1;
        }
        if (supports_.lateralFixed) constrained_[6 * n + static_cast<std::size_t>(l1)] = constrained_[6 * n + static_cast<std::size_t>(l2)] = 1;
      }
      if (!supports_.lateralFixed) {
        Vec3 centre = sp.box.origin + 0.5 * sp.box.size;
        centre[ax] = f == 0 ? lo : hi;
        Vec3 quarter = centre;
        quarter[l1] += 0.25 * sp.box.size[l1];
        auto nearest = [&](const Vec3& p, std::uint32_t skip) {
          std::uint32_t best = face[f].front() == skip ? face[f].back() : face[f].front();
          for (auto n : face[f])
            if (n != skip && (nodes_[n] - p).squaredNorm() < (nodes_[best] - p).squaredNorm()) best = n;
          return best;
        };
        const std::uint32_t c = nearest(centre, ~0u);
        constrained_[6 * c + static_cast<std::size_t>(l1)] = constrained_[6 * c + static_cast<std::size_t>(l2)] = 1;
        if (face[f].size() > 1) constrained_[6 * nearest(quarter, c) + static_cast<std::size_t>(l2)] = 1;
      }
    }
  }

  // Rotations are unknowns only when the law stiffens them (a truss lattice has none).
  bool rotations = false;
  for (const auto& p : props_) {
    const Mat12 probe = law_->stiffness(Vec3::UnitX(), 1.0, p.stiffness, section_);
    rotations = rotations || probe.diagonal().segment<3>(3).maxCoeff() > 0.0;
  }

  // Free dofs node by node in Morton order, so neighbours in space are neighbours in memory.
  std::vector<std::uint64_t> key(N);
  for (std::size_t n = 0; n < N; ++n) {
    std::uint64_t k = 0;
    for (int d = 0; d < 3; ++d) {
      const double t = std::clamp((nodes_[n][d] - sp.box.origin[d]) / sp.box.size[d], 0.0, 1.0);
      k |= spread(static_cast<std::uint64_t>(t * 2097151.0)) << d;
    }
    key[n] = k;
  }
  std::vector<std::uint32_t> order(N);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](auto a, auto b) { return key[a] < key[b]; });
  slotOf_.resize(N);
  for (std::uint32_t i = 0; i < N; ++i) slotOf_[order[i]] = i;
  nodeOfSlot_ = order;
  dofMap_.assign(6 * N, -1);
  blockOf_.assign(N, -1);
  auto& blockOf = blockOf_;
  std::int32_t next = 0;
  blockStart_.push_back(0);
  for (auto n : order) {
    if (nodeRodStart_[n + 1] == nodeRodStart_[n]) continue;
    const std::int32_t first = next;
    for (int k = 0; k < 6; ++k)
      if (!constrained_[6 * n + static_cast<std::size_t>(k)] && (k < 3 || rotations)) dofMap_[6 * n + static_cast<std::size_t>(k)] = next++;
    if (next == first) continue;
    blockOf[n] = static_cast<std::int32_t>(blockNode_.size());
    blockNode_.push_back(n);
    blockStart_.push_back(static_cast<std::uint32_t>(next));
  }
  const auto nFree = static_cast<Eigen::Index>(next);
  nodeBase_.assign(N, -1);
  freeMask_.assign(N, 0);
  for (std::size_t n = 0; n < N; ++n)
    for (int k = 0; k < 6; ++k)
      if (dofMap_[6 * n + static_cast<std::size_t>(k)] >= 0) {
        if (nodeBase_[n] < 0) nodeBase_[n] = dofMap_[6 * n + static_cast<std::size_t>(k)];
        freeMask_[n] = static_cast<std::uint8_t>(freeMask_[n] | (1u << k));
      }
  b_ = Eigen::VectorXd::Zero(nFree);
  h_ = Eigen::VectorXd::Zero(nFree);
  state_.assign(rods_.size(), kAlive);
  held_.assign(N, 0);
  for (std::uint32_t r = 0; r < rods_.size(); ++r)
    for (auto n : rods_[r])
      if (std::any_of(constrained_.begin() + 6 * n, constrained_.begin() + 6 * n + 6, [](auto c) { return c != 0; })) {
        boundaryRods_.push_back(r);
        break;
      }

  sweepOrder_.resize(blockNode_.size());
  std::iota(sweepOrder_.begin(), sweepOrder_.end(), 0u);
  std::vector<double> depth(blockNode_.size());
  for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
    const double z = nodes_[blockNode_[blk]][ax];
    depth[blk] = std::min(z - lo, hi - z);
  }
  std::stable_sort(sweepOrder_.begin(), sweepOrder_.end(), [&](auto a, auto b) { return depth[a] < depth[b]; });

  if (op_ == Operator::kMatrixFree) k_ = std::make_unique<MatrixFreeRods>(*this);
  else k_ = std::make_unique<AssembledBlocks>(*this);
  // b from the rods at the supports; the diagonal (kept for holding fragments) from the node blocks.
#pragma omp parallel for schedule(dynamic, 256)
  for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
    const std::uint32_t n = blockNode_[blk];
    for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
      const std::uint32_t r = nodeRods_[i];
      const int side = rods_[r][0] == n ? 0 : 1;
      bool touchesSupport = false;
      for (auto end : rods_[r])
        for (int k = 0; k < 6; ++k) touchesSupport = touchesSupport || prescribed_[6 * end + static_cast<std::size_t>(k)] != 0.0;
      if (touchesSupport) addSupportLoad(r, side, rodStiffness(r), 1.0);
    }
  }
  diagonal_.resize(nFree);
#pragma omp parallel for schedule(dynamic, 256)
  for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
    const Block d = diagonalBlock(blk);
    for (auto i = blockStart_[blk]; i < blockStart_[blk + 1]; ++i) diagonal_[i] = d(i - blockStart_[blk], i - blockStart_[blk]);
  }
}

Model::Model(Model&&) noexcept = default;
Model& Model::operator=(Model&&) noexcept = default;
Model::~Model() = default;

void Model::coupledSupports(const Specimen& sp) {
  const std::size_t N = nodes_.size();
  std::vector<std::uint8_t> taken(N, 0);
  bool dirichlet = false;
  for (const auto& cf : supports_.coupled) {
    const int ax = cf.face.axis;
    const double plane = sp.box.origin[ax] + (cf.face.side == 1 ? sp.box.size[ax] : 0.0), tol = 1e-9 * sp.box.size[ax];
    auto& nodes = faceNodes_.emplace_back();
    for (std::uint32_t n = 0; n < N; ++n) {
      if (taken[n] || nodeRodStart_[n + 1] == nodeRodStart_[n] || std::abs(nodes_[n][ax] - plane) > tol) continue;
      taken[n] = 1;
      nodes.push_back(n);
      if (cf.mode == FaceMode::kDirichlet)
        for (std::size_t k = 0; k < 3; ++k) constrained_[6 * n + k] = 1;
    }
    if (nodes.empty()) throw std::invalid_argument(fmt::format("coupled face {} has no rod ends", faceNodes_.size() - 1));
    dirichlet = dirichlet || cf.mode == FaceMode::kDirichlet;
  }
  if (!dirichlet) throw std::invalid_argument("no coupled face is dirichlet: nothing holds the lattice");
}

Mat12 Model::rodStiffness(std::size_t r) const { return lattice::rodStiffness(axis_[r], length_[r], springs_[r]); }

Model::SparseMatrix Model::stiffness() const { return k_->matrix(*this); }

std::int64_t Model::nonZeros() const { return k_->nonZeros(); }

Model::Vec6 Model::gather(std::uint32_t n, const Eigen::VectorXd& x) const {
  const std::uint8_t mask = freeMask_[n];
  if (mask == 0x3f) return x.segment<6>(nodeBase_[n]);  // an inner node: six consecutive free dofs
  Vec6 u = Vec6::Zero();
  for (int k = 0; k < 6; ++k)
    if (mask & (1u << k)) u[k] = x[dofMap_[6 * n + static_cast<std::size_t>(k)]];
  return u;
}

std::array<Model::Vec6, 2> Model::rodEndForces(std::size_t r, const Eigen::VectorXd& x) const {
  const Vec6 ua = gather(rods_[r][0], x), ub = gather(rods_[r][1], x);
  const Vec3& e = axis_[r];
  const RodSprings& k = springs_[r];
  std::array<Vec6, 2> l;
  detail::rodLoads(ua.data(), ub.data(), e[0], e[1], e[2], 0.5 * length_[r], k.shear, k.normal - k.shear, k.bending, k.torsion - k.bending,
           l[0].data(), l[1].data());
  return l;
}

void Model::addRodProducts(std::span<const std::uint32_t> rods, const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  for (const std::uint32_t r : rods) {
    const std::array<Vec6, 2> f = rodEndForces(r, x);
    for (int side = 0; side < 2; ++side) {
      const std::uint32_t n = rods_[r][static_cast<std::size_t>(side)];
      for (int c = 0; c < 6; ++c)
        if (const std::int32_t dof = dofMap_[6 * n + static_cast<std::size_t>(c)]; dof >= 0) y[dof] += f[static_cast<std::size_t>(side)][c];
    }
  }
}

Model::Vec6 Model::freeEntries(std::uint32_t n, const Vec6& full) const {
  Vec6 y = Vec6::Zero();
  int i = 0;
  for (int k = 0; k < 6; ++k)
    if (freeMask_[n] & (1u << k)) y[i++] = full[k];
  return y;
}

Model::Vec6 Model::blockProduct(std::size_t blk, const Eigen::VectorXd& x) const {
  return freeEntries(blockNode_[blk], k_->nodeProduct(*this, blk, x));
}

void Model::apply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const { k_->apply(*this, x, y); }

template <typename T>
void Model::pad(const Eigen::VectorXd& x, double scale, Eigen::Matrix<T, Eigen::Dynamic, 1>& x6) const {
  const std::size_t N = nodes_.size();
  x6.resize(static_cast<Eigen::Index>(6 * N));
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < N; ++i) {
    const std::uint32_t n = nodeOfSlot_[i];
    auto u = x6.template segment<6>(static_cast<Eigen::Index>(6 * i));
    const std::uint8_t mask = freeMask_[n];
    if (mask == 0x3f) {  // an inner node: six consecutive free dofs
      u = (scale * x.segment<6>(nodeBase_[n])).template cast<T>();
      continue;
    }
    u.setZero();
    for (int k = 0; k < 6; ++k)
      if (mask & (1u << k)) u[k] = static_cast<T>(scale * x[dofMap_[6 * n + static_cast<std::size_t>(k)]]);
  }
}

template void Model::pad<double>(const Eigen::VectorXd&, double, Eigen::VectorXd&) const;
template void Model::pad<float>(const Eigen::VectorXd&, double, Eigen::VectorXf&) const;

void Model::toPadded(const Eigen::VectorXd& x, double scale, Eigen::VectorXf& x6) const { pad(x, scale, x6); }

void Model::addFromPadded(const Eigen::VectorXf& x6, double scale, Eigen::VectorXd& x) const {
#pragma omp parallel for schedule(static)
  for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
    const std::uint32_t n = blockNode_[blk];
    auto k = static_cast<Eigen::Index>(blockStart_[blk]);
    const auto slot = static_cast<Eigen::Index>(6 * slotOf_[n]);
    for (int c = 0; c < 6; ++c)
      if (freeMask_[n] & (1u << c)) x[k++] += scale * static_cast<double>(x6[slot + c]);
  }
}

void Model::applySingle(const Eigen::VectorXf& x6, Eigen::VectorXf& y6) const {
  COSIM_ASSERT(x6.size() == paddedSize(), "{} entries for the padded space of {}", x6.size(), paddedSize());
  k_->applySingle(*this, x6, y6);
}

void Model::Stiffness::applySingle(const Model&, const Eigen::VectorXf&, Eigen::VectorXf&) const {
  COSIM_ASSERT(false, "the single-precision product needs the matrix-free operator");
}

Model::Block Model::diagonalBlock(std::size_t blk) const {
  const Block full = k_->nodeDiagonal(*this, blk);
  const std::uint32_t n = blockNode_[blk];
  std::array<int, 6> local{};
  int m = 0;
  for (int k = 0; k < 6; ++k)
    if (freeMask_[n] & (1u << k)) local[static_cast<std::size_t>(m++)] = k;
  Block d = Block::Zero();
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) d(i, j) = full(local[static_cast<std::size_t>(i)], local[static_cast<std::size_t>(j)]);
  return d;
}

void Model::addSupportLoad(std::size_t r, int side, const Mat12& k, double sign) {
  const std::uint32_t n = rods_[r][static_cast<std::size_t>(side)];
  if (blockOf_[n] < 0) return;  // a node without free dofs has no rows
  for (int a = 0; a < 6; ++a) {
    const std::int32_t row = dofMap_[6 * n + static_cast<std::size_t>(a)];
    if (row < 0) continue;
    for (int q = 0; q < 2; ++q) {
      const std::uint32_t node = rods_[r][static_cast<std::size_t>(q)];
      for (int c = 0; c < 6; ++c) {
        const std::size_t dof = 6 * node + static_cast<std::size_t>(c);
        if (dofMap_[dof] < 0 && prescribed_[dof] != 0.0) b_[row] -= sign * k(6 * side + a, 6 * q + c) * prescribed_[dof];
      }
    }
  }
}

Eigen::VectorXd Model::rhs(double strain) const { return strain * b_ + h_; }

Eigen::VectorXd Model::heldValues() const { return h_.cwiseQuotient(diagonal_); }

void Model::fullDisplacement(const Eigen::VectorXd& x, double strain, std::vector<double>& u) const {
  u.resize(dofMap_.size());
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < dofMap_.size(); ++i)
    u[i] = dofMap_[i] >= 0 ? x[dofMap_[i]] : strain * prescribed_[i];
}

double Model::rodStrain(std::size_t r, std::span<const double> u) const {
  const auto [a, b] = rods_[r];
  const Vec3 d(u[6 * b] - u[6 * a], u[6 * b + 1] - u[6 * a + 1], u[6 * b + 2] - u[6 * a + 2]);
  return d.dot(nodes_[b] - nodes_[a]) / (length_[r] * length_[r]);
}

Model::Vec6 Model::nodeForce(std::uint32_t n, std::span<const double> u) const {
  Vec6 f = Vec6::Zero();
  for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
    const std::uint32_t r = nodeRods_[i];
    if (state_[r] != kAlive) continue;
    const Mat12 k = rodStiffness(r);
    Eigen::Matrix<double, 12, 1> ur;
    for (int q = 0; q < 2; ++q)
      for (int c = 0; c < 6; ++c) ur[6 * q + c] = u[6 * rods_[r][static_cast<std::size_t>(q)] + static_cast<std::size_t>(c)];
    const int side = rods_[r][0] == n ? 0 : 1;
    f += k.middleRows<6>(6 * side) * ur;
  }
  return f;
}

double Model::reaction(std::span<const double> u) const {
  double sum = 0.0;
  for (std::uint32_t n = 0; n < nodes_.size(); ++n)
    if (movingFace_[n]) sum += nodeForce(n, u)[supports_.axis];
  return sum;
}

Eigen::VectorXd Model::rhs(std::span<const double> g, std::span<const double> f) const {
  COSIM_ASSERT(g.size() == dofMap_.size() && f.size() == dofMap_.size(), "{} and {} values for {} dofs", g.size(), f.size(),
               dofMap_.size());
  Eigen::VectorXd r = h_;
  for (std::size_t i = 0; i < dofMap_.size(); ++i)
    if (dofMap_[i] >= 0 && !held_[i / 6]) r[dofMap_[i]] += f[i];
  // −K_fc g over the rods that touch a constrained dof (the rows of their free, non-held ends).
  for (auto rod : boundaryRods_) {
    if (state_[rod] != kAlive) continue;
    Eigen::Matrix<double, 12, 1> ug = Eigen::Matrix<double, 12, 1>::Zero();
    for (std::size_t q = 0; q < 2; ++q)
      for (std::size_t c = 0; c < 6; ++c) {
        const std::size_t dof = 6 * rods_[rod][q] + c;
        if (constrained_[dof]) ug[static_cast<Eigen::Index>(6 * q + c)] = g[dof];
      }
    const Eigen::Matrix<double, 12, 1> load = rodStiffness(rod) * ug;
    for (std::size_t q = 0; q < 2; ++q) {
      const std::uint32_t n = rods_[rod][q];
      if (held_[n]) continue;
      for (std::size_t c = 0; c < 6; ++c)
        if (dofMap_[6 * n + c] >= 0) r[dofMap_[6 * n + c]] -= load[static_cast<Eigen::Index>(6 * q + c)];
    }
  }
  return r;
}

void Model::fullDisplacement(const Eigen::VectorXd& x, std::span<const double> g, std::vector<double>& u) const {
  u.resize(dofMap_.size());
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < dofMap_.size(); ++i) u[i] = dofMap_[i] >= 0 ? x[dofMap_[i]] : constrained_[i] ? g[i] : 0.0;
}

Model::Checkpoint Model::checkpoint() const {
  return {k_->values(), {}, b_, h_, state_, held_, removed_, heldCount_, removalLog_.size()};
}

void Model::restore(const Checkpoint& c) {
  COSIM_ASSERT(c.logSize <= removalLog_.size() && c.state.size() == state_.size(), "checkpoint of another model ({} of {} removals)",
               c.logSize, removalLog_.size());
  if (c.logSize == removalLog_.size() && c.heldCount == heldCount_) return;
  removalLog_.resize(c.logSize);
  assign(c);
}

void Model::assign(const Checkpoint& c) {
  b_ = c.b;
  h_ = c.h;
  state_ = c.state;
  held_ = c.held;
  removed_ = c.removed;
  heldCount_ = c.heldCount;
  k_->restore(*this, c.stiffness, c.layout);
  ++restores_;
}

void Model::Checkpoint::archive(common::StateArchive& a) {
  a.io("stiffness", stiffness), a.io("b", b), a.io("h", h), a.io("state", state), a.io("held", held);
  a.io("removed", removed), a.io("held_count", heldCount), a.io("log_size", logSize), a.io("layout", layout);
}

std::string Model::shape() const {
  return fmt::format("{} nodes, {} rods, {} free dofs, {} operator, {} stored values", nodes_.size(), rods_.size(), freeDofs(),
                     op_ == Operator::kAssembled ? "assembled" : "matrix-free", nonZeros());
}

void Model::archive(common::StateArchive& a) {
  auto scope = a.scope("model");
  Checkpoint c;
  if (!a.reading()) {
    c = checkpoint();
    c.layout = k_->layout();
  }
  c.archive(a);
  a.io("removal_log", removalLog_);
  if (!a.reading()) return;
  // A layout names each rod's record once: none (−1), or a distinct one among the rods.
  auto validLayout = [&](const std::vector<std::int32_t>& layout) {
    if (layout.empty()) return op_ == Operator::kAssembled;
    if (layout.size() != rods_.size()) return false;
    std::vector<std::uint8_t> seen(rods_.size(), 0);
    for (const std::int32_t i : layout)
      if (i >= 0 && (static_cast<std::size_t>(i) >= seen.size() || seen[static_cast<std::size_t>(i)]++)) return false;
    return true;
  };
  if (c.b.size() != b_.size() || c.h.size() != b_.size() || c.state.size() != state_.size() || c.held.size() != held_.size() ||
      c.logSize != removalLog_.size() || 36 * c.stiffness.size() != static_cast<std::size_t>(k_->nonZeros()) ||
      !validLayout(c.layout))
    throw common::ConfigError(fmt::format("{}: the lattice state does not fit this model ({})", a.path().string(), shape()));
  assign(c);
}

std::size_t Model::removeRods(std::span<const std::uint32_t> rods, const Eigen::VectorXd& x) {
  for (auto r : rods) {
    COSIM_ASSERT(active(r), "rod {} is not active", r);
    state_[r] = kRemoved;
    ++removed_;
    removalLog_.push_back(r);
    const Mat12 k = rodStiffness(r);
    k_->remove(*this, r, k);
    addSupportLoad(r, 0, k, -1.0);
    addSupportLoad(r, 1, k, -1.0);
  }
  return endsStillConnected(rods) ? 0 : holdDetached(x);
}

bool Model::endsStillConnected(std::span<const std::uint32_t> rods) const {
  // Removing rods leaves the lattice's pieces as they were exactly when the two ends of every removed
  // rod are still connected. A search of a few hundred nodes from one end nearly always meets the other
  // (the two usually share a neighbour); the whole lattice is searched (holdDetached) only when it
  // does not.
  constexpr std::size_t kBudget = 256;
  if (reached_.size() != nodes_.size()) reached_.assign(nodes_.size(), 0);
  std::vector<std::uint32_t> visited;
  for (const std::uint32_t r : rods) {
    const std::uint32_t from = rods_[r][0], to = rods_[r][1];
    visited.assign(1, from);
    reached_[from] = 1;
    bool found = false;
    for (std::size_t head = 0; head < visited.size() && visited.size() < kBudget && !found; ++head) {
      const std::uint32_t n = visited[head];
      for (auto i = nodeRodStart_[n]; i < nodeRodStart_[n + 1]; ++i) {
        const std::uint32_t q = nodeRods_[i];
        if (state_[q] != kAlive) continue;
        const std::uint32_t m = rods_[q][0] == n ? rods_[q][1] : rods_[q][0];
        if (m == to) {
          found = true;
          break;
        }
        if (!reached_[m]) {
          reached_[m] = 1;
          visited.push_back(m);
        }
      }
    }
    for (const std::uint32_t n : visited) reached_[n] = 0;
    if (!found) return false;
  }
  return true;
}

std::size_t Model::holdDetached(const Eigen::VectorXd& x) {
  const std::size_t N = nodes_.size();
  std::vector<std::uint32_t> parent(N);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::vector<std::uint8_t> hasRod(N, 0);
  for (std::size_t r = 0; r < rods_.size(); ++r)
    if (state_[r] == kAlive) {
      hasRod[rods_[r][0]] = hasRod[rods_[r][1]] = 1;
      const auto a = find(rods_[r][0]), b = find(rods_[r][1]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  // A node with no rod left is held even on a support: its free dofs (rotations, lateral translations)
  // have no stiffness at all.
  std::vector<std::uint8_t> supported(N, 0);
  for (std::size_t n = 0; n < N; ++n)
    for (int k = 0; k < 6; ++k)
      if (constrained_[6 * n + static_cast<std::size_t>(k)] && hasRod[n]) supported[find(static_cast<std::uint32_t>(n))] = 1;
  std::size_t fresh = 0;
  for (std::size_t blk = 0; blk < blockNode_.size(); ++blk) {
    const std::uint32_t n = blockNode_[blk];
    if (held_[n] || supported[find(n)]) continue;
    held_[n] = 1;
    ++fresh;
    // Rows (and the matching columns) become the original diagonal: the dofs keep the value of x.
    for (auto row = blockStart_[blk]; row < blockStart_[blk + 1]; ++row) {
      b_[row] = 0.0;
      h_[row] = diagonal_[row] * x[row];
    }
    k_->hold(*this, blk);
  }
  heldCount_ += fresh;
  if (fresh > 0) k_->afterHolds(*this);
  return fresh;
}

}  // namespace lattice
