// The barycentric mapping (cosim/mapping.hpp): each "to" node takes the values of the "from" cell that
// contains it (a tetrahedron, a triangle or a segment), weighted by its barycentric coordinates — the
// linear shape functions N_I(X) of that cell. It reproduces every linear field exactly, and its
// transpose (forces) keeps Σ f and, since Σ N_I(X) X_I = X, Σ X × f too. Made for a bridging domain,
// where the particles lie inside the continuum's elements: a node in no cell is an error, not a
// projection.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <vector>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "mappings.hpp"

namespace cosim {

namespace {

// A point on a cell's face or end counts as inside: coordinates down to −kInside; off a triangle's plane
// or a segment's line by at most kOff of the cell's size.
constexpr double kInside = 1e-9, kOff = 1e-6;

struct Hit {
  std::vector<std::uint32_t> nodes;
  std::vector<double> weights;
  double worst = -std::numeric_limits<double>::infinity();  // the smallest coordinate: larger is deeper inside
};

void consider(Hit& best, std::vector<std::uint32_t> nodes, std::vector<double> weights) {
  const double worst = *std::min_element(weights.begin(), weights.end());
  if (worst < -kInside || worst <= best.worst) return;
  best = {std::move(nodes), std::move(weights), worst};
}

void inTetrahedron(Hit& best, const InterfaceMesh& m, const std::array<std::uint32_t, 4>& c, const Vec3& p) {
  const Vec3& x0 = m.nodes[c[0]];
  Eigen::Matrix3d J;
  J << m.nodes[c[1]] - x0, m.nodes[c[2]] - x0, m.nodes[c[3]] - x0;
  const double det = J.determinant();
  if (!(std::abs(det) > 0.0)) return;  // a flat cell holds no point
  const Vec3 l = J.inverse() * (p - x0);
  consider(best, {c[0], c[1], c[2], c[3]}, {1.0 - l.sum(), l[0], l[1], l[2]});
}

void inTriangle(Hit& best, const InterfaceMesh& m, const std::array<std::uint32_t, 3>& c, const Vec3& p) {
  const Vec3 &a = m.nodes[c[0]], e1 = m.nodes[c[1]] - a, e2 = m.nodes[c[2]] - a;
  const Vec3 n = e1.cross(e2);
  const double area2 = n.squaredNorm();
  if (!(area2 > 0.0)) return;
  const Vec3 d = p - a;
  const double size = std::max({e1.norm(), e2.norm(), (e2 - e1).norm()});
  if (std::abs(d.dot(n)) / std::sqrt(area2) > kOff * size) return;
  const double l1 = d.cross(e2).dot(n) / area2, l2 = e1.cross(d).dot(n) / area2;
  consider(best, {c[0], c[1], c[2]}, {1.0 - l1 - l2, l1, l2});
}

void inSegment(Hit& best, const InterfaceMesh& m, const std::array<std::uint32_t, 2>& c, const Vec3& p) {
  const Vec3 &a = m.nodes[c[0]], e = m.nodes[c[1]] - a;
  const double len2 = e.squaredNorm();
  if (!(len2 > 0.0)) return;
  const double t = (p - a).dot(e) / len2;
  if ((p - a - t * e).norm() > kOff * std::sqrt(len2)) return;
  consider(best, {c[0], c[1]}, {1.0 - t, t});
}

// The source mesh's cells by the buckets of a uniform grid that their boxes overlap, each box widened by
// 1e-5 of its cell's size (more than the tolerances above). A point is tested against the cells of its
// bucket only, in the order of a scan of them all — tetrahedra, triangles, segments, each by index — so
// it finds the cell that scan would: a cell whose box misses the point cannot hold it. Setting up a
// bridging overlap of n particles in m cells then costs about n + m tests, not n × m (1,800 × 1,333
// on the slab of docs/validation/bridging.md).
class CellGrid {
  using Buckets = Eigen::Array<long, 3, 1>;

 public:
  explicit CellGrid(const InterfaceMesh& m) : m_(m) {
    const std::size_t cells = m.tetrahedra.size() + m.triangles.size() + m.segments.size();
    if (cells == 0)
      throw std::invalid_argument("barycentric mapping: the source mesh has no cells (tetrahedra, triangles or "
                                  "segments) to interpolate in");
    std::vector<Eigen::AlignedBox3d> box(cells);
    double sizes = 0.0;
    for (std::size_t g = 0; g < cells; ++g) {
      forNodes(g, [&](std::uint32_t n) { box[g].extend(m.nodes[n]); });
      const double size = box[g].sizes().maxCoeff();
      box[g].min().array() -= 1e-5 * size, box[g].max().array() += 1e-5 * size;
      sizes += size, all_.extend(box[g]);
    }
    // Buckets about the mean cell's size, at most 8 per cell (a few very large cells make it coarser).
    h_ = std::max(sizes / static_cast<double>(cells), 1e-300);
    const Eigen::Array3d extent = all_.sizes().array().max(1e-300);
    while (((extent / h_).floor() + 1).prod() > 8.0 * static_cast<double>(cells) + 27) h_ *= 1.5;
    dims_ = ((extent / h_).floor() + 1).cast<long>();
    auto forBuckets = [&](std::size_t g, auto&& f) {
      const Buckets lo = bucketOf(box[g].min()), hi = bucketOf(box[g].max());
      for (long z = lo.z(); z <= hi.z(); ++z)
        for (long y = lo.y(); y <= hi.y(); ++y)
          for (long x = lo.x(); x <= hi.x(); ++x) f(static_cast<std::size_t>((z * dims_.y() + y) * dims_.x() + x));
    };
    start_.assign(static_cast<std::size_t>(dims_.prod()) + 1, 0);
    for (std::size_t g = 0; g < cells; ++g) forBuckets(g, [&](std::size_t b) { ++start_[b + 1]; });
    std::partial_sum(start_.begin(), start_.end(), start_.begin());
    items_.resize(start_.back());
    std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t g = 0; g < cells; ++g)
      forBuckets(g, [&](std::size_t b) { items_[fill[b]++] = static_cast<std::uint32_t>(g); });
  }

  // The cell of this mesh deepest around p, as a scan of every cell would find it.
  Hit locate(const Vec3& p) const {
    Hit best;
    if (!all_.contains(p)) return best;
    const Buckets c = bucketOf(p);
    const auto b = static_cast<std::size_t>((c.z() * dims_.y() + c.y()) * dims_.x() + c.x());
    const std::size_t nt = m_.tetrahedra.size(), nf = m_.triangles.size();
    for (std::uint32_t k = start_[b]; k < start_[b + 1]; ++k) {
      const std::size_t g = items_[k];
      if (g < nt) inTetrahedron(best, m_, m_.tetrahedra[g], p);
      else if (g < nt + nf) inTriangle(best, m_, m_.triangles[g - nt], p);
      else inSegment(best, m_, m_.segments[g - nt - nf], p);
    }
    return best;
  }

 private:
  template <class F>
  void forNodes(std::size_t g, F&& f) const {
    const std::size_t nt = m_.tetrahedra.size(), nf = m_.triangles.size();
    if (g < nt) for (auto n : m_.tetrahedra[g]) f(n);
    else if (g < nt + nf) for (auto n : m_.triangles[g - nt]) f(n);
    else for (auto n : m_.segments[g - nt - nf]) f(n);
  }
  Buckets bucketOf(const Vec3& x) const {
    return ((x - all_.min()).array() / h_).floor().cast<long>().max(0).min(dims_ - 1);
  }

  const InterfaceMesh& m_;
  Eigen::AlignedBox3d all_;
  double h_ = 1.0;
  Buckets dims_ = Buckets::Zero();
  std::vector<std::uint32_t> start_, items_;  // bucket b's cells: items_[start_[b] .. start_[b + 1]), ascending
};

// The cell that holds `to` node i, deepest inside where it lies on shared faces.
Hit locate(const InterfaceMesh& from, const CellGrid& grid, const InterfaceMesh& to, std::size_t i) {
  const std::size_t cells = from.tetrahedra.size() + from.triangles.size() + from.segments.size();
  const Vec3& p = to.nodes[i];
  Hit best = grid.locate(p);
  if (best.nodes.empty())
    throw std::invalid_argument(fmt::format(
        "barycentric mapping: node {} at ({:.6g}, {:.6g}, {:.6g}) lies in none of the source mesh's {} cells "
        "({} tetrahedra, {} triangles, {} segments): every point of the target must lie inside the source",
        i, p.x(), p.y(), p.z(), cells, from.tetrahedra.size(), from.triangles.size(), from.segments.size()));
  return best;
}

class Barycentric final : public Mapping {
 public:
  Barycentric(const InterfaceMesh& from, const InterfaceMesh& to) {
    const CellGrid grid(from);
    std::vector<Eigen::Triplet<double>> t;
    for (std::size_t i = 0; i < to.nodes.size(); ++i) {
      Hit best = locate(from, grid, to, i);
      // Clipped to the cell: a point on a face gets no weight of the wrong sign, and the row sums to one.
      double sum = 0.0;
      for (double& w : best.weights) sum += (w = std::max(w, 0.0));
      for (std::size_t k = 0; k < best.nodes.size(); ++k)
        if (best.weights[k] > 0.0)
          t.emplace_back(static_cast<int>(i), static_cast<int>(best.nodes[k]), best.weights[k] / sum);
    }
    setMatrix(t, to.nodes.size(), from.nodes.size());
  }
  std::string name() const override { return "barycentric"; }
};

}  // namespace

std::unique_ptr<Mapping> makeBarycentric(const InterfaceMesh& from, const InterfaceMesh& to) {
  return std::make_unique<Barycentric>(from, to);
}

Eigen::SparseMatrix<double> spinMatrix(const InterfaceMesh& from, const InterfaceMesh& to) {
  if (from.tetrahedra.empty() || !from.triangles.empty() || !from.segments.empty())
    throw std::invalid_argument("spin of a linear field: the source mesh must be of tetrahedra only (a triangle or a "
                                "segment has no gradient across it)");
  std::vector<Eigen::Triplet<double>> t;
  const CellGrid grid(from);
  for (std::size_t i = 0; i < to.nodes.size(); ++i) {
    const Hit hit = locate(from, grid, to, i);
    const Vec3& x0 = from.nodes[hit.nodes[0]];
    Eigen::Matrix3d J;
    J << from.nodes[hit.nodes[1]] - x0, from.nodes[hit.nodes[2]] - x0, from.nodes[hit.nodes[3]] - x0;
    // Rows 1–3 of J⁻¹ are the gradients of the barycentric coordinates 1–3; theirs sum to minus node 0's.
    const Eigen::Matrix3d G = J.inverse();
    for (int k = 0; k < 4; ++k) {
      const Vec3 grad = k == 0 ? Vec3(-G.colwise().sum().transpose()) : Vec3(G.row(k - 1).transpose());
      // ½ ∇N × v as ½ [∇N]ₓ v.
      const Eigen::Matrix3d cross = 0.5 * (Eigen::Matrix3d() << 0, -grad.z(), grad.y(), grad.z(), 0, -grad.x(),
                                           -grad.y(), grad.x(), 0).finished();
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          if (cross(r, c) != 0.0)
            t.emplace_back(static_cast<int>(3 * i) + r, static_cast<int>(3 * hit.nodes[static_cast<std::size_t>(k)]) + c,
                           cross(r, c));
    }
  }
  Eigen::SparseMatrix<double> m(static_cast<Eigen::Index>(3 * to.nodes.size()),
                                static_cast<Eigen::Index>(3 * from.nodes.size()));
  m.setFromTriplets(t.begin(), t.end());
  return m;
}

}  // namespace cosim
