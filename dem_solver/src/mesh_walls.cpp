// Sphere–triangle-mesh contacts: candidates (rebuilt with the Verlet skin), the face/edge/vertex rule of
// dem/mesh_wall.hpp, history hand-over, and the force split to the nodes.
#include "mesh_walls.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <span>
#include <tuple>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/geometry.hpp"
#include "contact/tangential.hpp"
#include "per_thread.hpp"

namespace dem {

namespace {

enum FeatureKind : std::uint64_t { kFace = 0, kEdge = 1, kVertex = 2 };

std::uint64_t featureKey(FeatureKind kind, std::uint64_t a, std::uint64_t b = 0) {
  return (static_cast<std::uint64_t>(kind) << 62) | (std::min(a, b) << 31) | std::max(a, b);
}

struct Hit {
  std::uint32_t triangle;
  common::ClosestPoint cp;
  FeatureKind kind;
  std::uint64_t key;
  std::uint32_t nodeA, nodeB;  // the edge's nodes, or the vertex (nodeA)
  bool behind;                 // one-sided sheet: the centre is through it at this feature
  Vec3 normal;                 // unit normal of the triangle
  double weight;               // its share of the feature's pseudo-normal (the angle at a vertex)
};

}  // namespace

double MeshWalls::automaticSkin(const Spheres& spheres, double pairSkin) const {
  // Sphere–mesh candidates per sphere hardly grow while the skin is small against the triangles, and a
  // net moving at metres per second used up a 0.2 r skin every few steps (c7 rockfall block: 0.2 r →
  // 1.6 r = edge / 10 halved the DEM time, same results). So: a tenth of the median triangle edge, at
  // most twice the largest radius (huge floor triangles), at least the pair skin.
  std::vector<double> edges;
  for (const auto& w : walls_)
    for (const auto& t : w.triangles)
      for (int k = 0; k < 3; ++k) edges.push_back((w.nodes[t[(k + 1) % 3]] - w.nodes[t[k]]).norm());
  if (edges.empty() || spheres.size() == 0) return pairSkin;
  std::nth_element(edges.begin(), edges.begin() + static_cast<std::ptrdiff_t>(edges.size() / 2), edges.end());
  const double rmax = *std::max_element(spheres.radius.begin(), spheres.radius.end());
  return std::max(pairSkin, std::min(0.1 * edges[edges.size() / 2], 2.0 * rmax));
}

void MeshWalls::clearContacts() {
  contacts_ = MeshContacts{};
  for (auto& w : walls_) {
    std::fill(w.nodeForce.begin(), w.nodeForce.end(), Vec3::Zero());
    w.force.setZero(), w.moment.setZero();
  }
  power_ = 0.0;
}

void MeshWalls::rebuildCandidates(const StepContext& ctx) {
  MeshContacts& mc = contacts_;
  const Spheres& spheres = ctx.spheres;
  mc.candidates.clear();
  const double skin = ctx.settings.meshSkin;
  for (std::uint32_t m = 0; m < walls_.size(); ++m) {
    const MeshWall& w = walls_[m];
    // Bin triangles (boxes grown by the skin) on a grid of cells about twice the largest sphere.
    double rmax = 0.0;
    for (double r : spheres.radius) rmax = std::max(rmax, r);
    common::Aabb all;
    std::vector<common::Aabb> boxes(w.triangles.size());
    for (std::size_t t = 0; t < w.triangles.size(); ++t) {
      for (auto n : w.triangles[t]) boxes[t].expand(w.nodes[n]);
      boxes[t] = boxes[t].inflated(skin);
      all.expand(boxes[t]);
    }
    double cell = std::max(2.0 * rmax + skin, 1e-12);
    while (((all.extent() / cell).array() + 1).prod() > 4.0 * static_cast<double>(w.triangles.size()) + 64) cell *= 1.5;
    const Eigen::Array3i dims = ((all.extent() / cell).array().floor() + 1).cast<int>();
    auto cellOf = [&](const Vec3& p) {
      return ((p - all.min) / cell).array().floor().cast<int>().max(0).min(dims - 1).eval();
    };
    std::vector<std::vector<std::uint32_t>> bins(static_cast<std::size_t>(dims.prod()));
    auto binIndex = [&](const Eigen::Array3i& c) {
      return static_cast<std::size_t>((c.z() * dims.y() + c.y()) * dims.x() + c.x());
    };
    for (std::uint32_t t = 0; t < w.triangles.size(); ++t) {
      const Eigen::Array3i lo = cellOf(boxes[t].min), hi = cellOf(boxes[t].max);
      for (int z = lo.z(); z <= hi.z(); ++z)
        for (int y = lo.y(); y <= hi.y(); ++y)
          for (int x = lo.x(); x <= hi.x(); ++x) bins[binIndex({x, y, z})].push_back(t);
    }
    const auto ns = static_cast<std::ptrdiff_t>(spheres.size());
    detail::PerThread<std::vector<MeshCandidate>> local(static_cast<std::size_t>(omp_get_max_threads()));
#pragma omp parallel if (ns > kParallelMin)
    {
      auto& mine = local[static_cast<std::size_t>(omp_get_thread_num())];
      std::vector<std::uint32_t> near;
#pragma omp for schedule(static)
      for (std::ptrdiff_t si = 0; si < ns; ++si) {
        const auto s = static_cast<std::uint32_t>(si);
        if (ctx.lawOf[spheres.material[s] * ctx.materials + w.material] < 0) continue;
        if (ghost(ctx.bodies.fixed[spheres.body[s]])) continue;
        const Vec3& x = spheres.position[s];
        // A one-sided sheet keeps centres up to depthRadii behind it in contact.
        const double extent = spheres.radius[s] * (w.oneSided ? std::max(1.0, w.depthRadii) : 1.0);
        const double reach = extent + skin;
        if (all.distance(x) > extent) continue;
        const Eigen::Array3i lo = cellOf(x.array() - extent), hi = cellOf(x.array() + extent);
        near.clear();
        for (int z = lo.z(); z <= hi.z(); ++z)
          for (int y = lo.y(); y <= hi.y(); ++y)
            for (int xx = lo.x(); xx <= hi.x(); ++xx) {
              const auto& bin = bins[binIndex({xx, y, z})];
              near.insert(near.end(), bin.begin(), bin.end());
            }
        std::sort(near.begin(), near.end());
        near.erase(std::unique(near.begin(), near.end()), near.end());
        for (auto t : near) {
          const auto& tri = w.triangles[t];
          const auto cp = common::closestPointOnTriangle(x, w.nodes[tri[0]], w.nodes[tri[1]], w.nodes[tri[2]]);
          if (cp.distanceSquared >= reach * reach) continue;
          // Beyond a radius only what is behind a one-sided sheet can be a contact (the face normal is a
          // cheap test here; the contact rule decides with the pseudo-normal, and the skin covers both).
          const double front = spheres.radius[s] + skin;
          if (cp.distanceSquared >= front * front &&
              (x - cp.point).dot((w.nodes[tri[1]] - w.nodes[tri[0]]).cross(w.nodes[tri[2]] - w.nodes[tri[0]])) >= 0.0)
            continue;
          mine.push_back({s, m, t});
        }
      }
    }
    local.forEach([&](const std::vector<MeshCandidate>& l) { mc.candidates.insert(mc.candidates.end(), l.begin(), l.end()); });
  }
  std::sort(mc.candidates.begin(), mc.candidates.end());
  mc.candidateTriangles.assign(walls_.size(), {});
  for (const auto& c : mc.candidates) mc.candidateTriangles[c.mesh].push_back(c.triangle);
  for (auto& t : mc.candidateTriangles) {
    std::sort(t.begin(), t.end());
    t.erase(std::unique(t.begin(), t.end()), t.end());
  }
  // Groups: runs of candidates with the same (sphere, mesh).
  mc.groups.clear();
  for (std::size_t i = 0; i < mc.candidates.size();) {
    std::size_t j = i;
    while (j < mc.candidates.size() && mc.candidates[j].sphere == mc.candidates[i].sphere &&
           mc.candidates[j].mesh == mc.candidates[i].mesh)
      ++j;
    mc.groups.push_back({i, j});
    i = j;
  }
}

namespace {

// Per thread and mesh: contacts lost through a one-sided sheet, and the deepest centre behind one [radii].
struct SheetTally {
  explicit SheetTally(std::size_t meshes)
      : meshes(meshes), lostBy(static_cast<std::size_t>(omp_get_max_threads()) * meshes, 0), deepestBy(lostBy.size(), 0.0) {}
  std::int64_t& lost(std::size_t m) { return lostBy[static_cast<std::size_t>(omp_get_thread_num()) * meshes + m]; }
  double& deepest(std::size_t m) { return deepestBy[static_cast<std::size_t>(omp_get_thread_num()) * meshes + m]; }
  std::size_t meshes;
  std::vector<std::int64_t> lostBy;
  std::vector<double> deepestBy;
};

// History of a sphere's new contacts with one mesh: the previous step's contact on the same feature,
// else the unclaimed previous contact of that sphere and mesh with the closest normal (within 45°).
// The previous contacts are ordered by (law, sphere, mesh), so a sphere's are one run found by
// bisection: no map over all contacts, and each group touches only its own run (safe in parallel).
// Appends the histories of `out` (one group's new contacts) to `all`.
void matchHistory(const MeshContacts& mc, std::span<const MeshContact> out, std::vector<ContactHistory>& all) {
  const std::size_t base = all.size();
  all.resize(base + out.size());
  const auto history = std::span(all).subspan(base);
  if (out.empty() || mc.previous.empty()) return;
  const auto order = [](const MeshContact& c) { return std::tuple(c.law, c.sphere, c.mesh); };
  const auto [first, last] = std::equal_range(
      mc.previous.begin(), mc.previous.end(), out.front(),
      [&](const MeshContact& a, const MeshContact& b) { return order(a) < order(b); });
  if (first == last) return;
  const auto offset = static_cast<std::size_t>(first - mc.previous.begin());
  const auto count = static_cast<std::size_t>(last - first);
  thread_local std::vector<char> claimed;
  thread_local std::vector<std::size_t> unmatched;
  claimed.assign(count, 0);
  unmatched.clear();
  for (std::size_t i = 0; i < out.size(); ++i) {
    std::size_t k = 0;
    while (k < count && (claimed[k] || mc.previous[offset + k].key != out[i].key)) ++k;
    if (k < count) {
      history[i] = mc.previousHistory[offset + k];
      claimed[k] = 1;
    } else {
      unmatched.push_back(i);
    }
  }
  for (auto i : unmatched) {
    std::size_t best = count;
    double bestDot = std::cos(3.14159265358979 / 4);
    for (std::size_t k = 0; k < count; ++k) {
      if (claimed[k]) continue;
      const double d = mc.previous[offset + k].point.normal.dot(out[i].point.normal);
      if (d > bestDot) {
        bestDot = d;
        best = k;
      }
    }
    if (best < count) {
      history[i] = mc.previousHistory[offset + best];
      claimed[best] = 1;
    }
  }
}

// The contact of sphere `s` with mesh `m` at the kept hit `h`; `deepest`: this thread's deepest centre
// behind the sheet so far [radii].
MeshContact meshContact(const StepContext& ctx, const MeshWall& w, std::uint32_t s, std::uint32_t m, const Hit& h,
                        double& deepest) {
  const Spheres& spheres = ctx.spheres;
  const Bodies& bodies = ctx.bodies;
  const Vec3& x = ctx.centres[s];
  const double r = spheres.radius[s];
  MeshContact c;
  c.sphere = s;
  c.mesh = m;
  c.triangle = h.triangle;
  c.key = h.key;
  c.law = ctx.lawOf[spheres.material[s] * ctx.materials + w.material];
  c.bary = h.cp.bary;
  c.wallPoint = h.cp.point;
  double dist = std::sqrt(h.cp.distanceSquared);
  const auto& tri = w.triangles[h.triangle];
  const Vec3& face = h.normal;
  Vec3 normal;
  if (h.behind) {
    // The centre went through a one-sided sheet: the overlap is counted through it (r + distance, no
    // tunnelling under large overlaps) and the force pushes the centre towards its closest point,
    // along the gradient of that overlap (the face normal for a face; for an edge or vertex the
    // face normal would make the force field non-conservative).
    normal = dist > 1e-12 * r ? Vec3((h.cp.point - x) / dist) : face;
    deepest = std::max(deepest, dist / r);
    dist = -dist;
  } else if (dist > 1e-12 * r) {
    normal = (x - h.cp.point) / dist;
  } else {  // centre on the surface: fall back to the face normal
    normal = face;
  }
  ContactPoint& p = c.point;
  p.overlap = r - dist;
  p.normal = normal;
  p.point = x - normal * (r - 0.5 * p.overlap);
  const auto b = spheres.body[s];
  c.wallVelocity = h.cp.bary[0] * w.nodeVelocity[tri[0]] + h.cp.bary[1] * w.nodeVelocity[tri[1]] +
                   h.cp.bary[2] * w.nodeVelocity[tri[2]];
  p.relVelocity =
      bodies.velocity[b] + bodies.angularVelocity[b].cross(p.point - bodies.position[b]) - c.wallVelocity;
  p.effRadius = r;
  p.effMass = bodies.mass[b];
  if (!w.nodeMass.empty()) {
    const double mw = h.cp.bary[0] * w.nodeMass[tri[0]] + h.cp.bary[1] * w.nodeMass[tri[1]] +
                      h.cp.bary[2] * w.nodeMass[tri[2]];
    p.effMass = p.effMass * mw / (p.effMass + mw);
  }
  return c;
}

// One (sphere, mesh) group of `mc`: its contacts appended to `out`, their histories to `history`; what a
// one-sided sheet lost or let through goes into this thread's row of `sheets`. On one thread `out` and
// `history` are mc.contacts and mc.history themselves: of `mc` it reads only the candidates, the groups,
// the face normals and the previous step's contacts.
void groupContacts(const StepContext& ctx, const MeshContacts& mc, const std::vector<MeshWall>& walls, std::size_t g,
                   std::vector<MeshContact>& out, std::vector<ContactHistory>& history, SheetTally& sheets) {
  const std::size_t first = out.size();
  const auto [begin, end] = mc.groups[g];
  const std::uint32_t s = mc.candidates[begin].sphere, m = mc.candidates[begin].mesh;
  const MeshWall& w = walls[m];
  const Vec3& x = ctx.centres[s];
  const double r = ctx.spheres.radius[s];
  thread_local std::vector<Hit> hits;  // reused: this runs per sphere and step
  hits.clear();
  for (std::size_t k = begin; k < end; ++k) {
    const std::uint32_t t = mc.candidates[k].triangle;
    const auto& tri = w.triangles[t];
    const Vec3& faceNormal = mc.scratch->faceNormals[m][t];
    // In front of the face's plane by more than a radius: no point of the triangle is within reach and
    // the centre is not behind it — the closest-point test below would drop it too (the margin covers
    // its round-off). Most candidates of a block resting on a net are such neighbours.
    if ((x - w.nodes[tri[0]]).dot(faceNormal) > r * (1.0 + 1e-9)) continue;
    const auto cp = common::closestPointOnTriangle(x, w.nodes[tri[0]], w.nodes[tri[1]], w.nodes[tri[2]]);
    const bool behind = w.oneSided && (x - cp.point).dot(faceNormal) < 0.0;
    if (cp.distanceSquared >= r * r && !(behind && cp.distanceSquared < w.depthRadii * w.depthRadii * r * r)) {
      if (behind && cp.feature == common::TriangleFeature::kFace)
        ++sheets.lost(m);
      continue;
    }
    Hit h{t, cp, kFace, 0, 0, 0, behind, faceNormal, 1.0};
    using F = common::TriangleFeature;
    switch (cp.feature) {
      case F::kFace: h.key = featureKey(kFace, t); break;
      case F::kEdgeAB: h = {t, cp, kEdge, 0, tri[0], tri[1], behind, faceNormal, 1.0}; break;
      case F::kEdgeBC: h = {t, cp, kEdge, 0, tri[1], tri[2], behind, faceNormal, 1.0}; break;
      case F::kEdgeCA: h = {t, cp, kEdge, 0, tri[2], tri[0], behind, faceNormal, 1.0}; break;
      case F::kVertexA: h = {t, cp, kVertex, 0, tri[0], tri[0], behind, faceNormal, 1.0}; break;
      case F::kVertexB: h = {t, cp, kVertex, 0, tri[1], tri[1], behind, faceNormal, 1.0}; break;
      case F::kVertexC: h = {t, cp, kVertex, 0, tri[2], tri[2], behind, faceNormal, 1.0}; break;
    }
    if (h.kind == kEdge) h.key = featureKey(kEdge, h.nodeA, h.nodeB);
    if (h.kind == kVertex) {
      h.key = featureKey(kVertex, h.nodeA, h.nodeA);
      const int c = h.nodeA == tri[0] ? 0 : h.nodeA == tri[1] ? 1 : 2;  // the angle of the face at the vertex
      const Vec3 e1 = w.nodes[tri[(c + 1) % 3]] - w.nodes[tri[c]], e2 = w.nodes[tri[(c + 2) % 3]] - w.nodes[tri[c]];
      h.weight = std::atan2(e1.cross(e2).norm(), e1.dot(e2));
    }
    hits.push_back(h);
  }
  if (w.oneSided) {
    // Behind an edge or vertex is decided by its pseudo-normal (the sum of the normals of the faces that
    // share it, angle-weighted at a vertex; Bærentzen & Aanæs 2005): the sign of the distance is then
    // continuous as a centre moves from one face's prism to a neighbour's, on a folded sheet too. Every
    // face sharing the feature is a candidate (each is exactly as near). A centre beside the sheet
    // deeper than a radius is out of reach.
    for (auto& h : hits) {
      if (h.kind == kFace) continue;
      Vec3 pseudo = Vec3::Zero();
      for (const auto& o : hits)
        if (o.key == h.key) pseudo += o.weight * o.normal;
      h.behind = (x - h.cp.point).dot(pseudo) < 0.0;
    }
    std::erase_if(hits, [&](const Hit& h) { return !h.behind && h.cp.distanceSquared >= r * r; });
    // The nearest point decides the side (the signed distance of the sheet). Through the sheet: one
    // contact there, overlap r + distance. In front: the usual front contacts, and no behind ones.
    // (Other hits on the far side are the same sheet seen again — a bowl around a sunk sphere, a fold
    // — and counting them makes contacts, with their stored energy, appear and vanish as it moves.)
    const Hit* nearest = nullptr;
    for (const auto& h : hits)
      if (!nearest || h.cp.distanceSquared < nearest->cp.distanceSquared) nearest = &h;
    if (nearest && nearest->behind) {
      const Hit only = *nearest;
      hits.assign(1, only);
    } else {
      std::erase_if(hits, [](const Hit& h) { return h.behind; });
    }
  }
  if (hits.empty()) return;
  // The rule of dem/mesh_wall.hpp: faces before edges before vertices, nearer first; a hit is dropped
  // when the same feature was kept, or when its closest point is not in front of the tangent plane of
  // a kept contact (it is hidden behind it: flat neighbours, the far side of a ridge).
  std::sort(hits.begin(), hits.end(), [](const Hit& a, const Hit& b) {
    return a.kind != b.kind ? a.kind < b.kind : a.cp.distanceSquared < b.cp.distanceSquared;
  });
  const double tolerance = 1e-9 * r;
  for (const auto& h : hits) {
    bool hidden = false;
    for (std::size_t i = first; i < out.size(); ++i) {
      const MeshContact& c = out[i];
      if (c.key == h.key || (h.cp.point - c.wallPoint).dot(c.point.normal) <= tolerance) {
        hidden = true;
        break;
      }
    }
    if (!hidden) out.push_back(meshContact(ctx, w, s, m, h, sheets.deepest(m)));
  }
  matchHistory(mc, std::span<const MeshContact>(out).subspan(first), history);
}

}  // namespace

void MeshWalls::computeContacts(const StepContext& ctx) {
  MeshContacts& mc = contacts_;
  // Keep last step's contacts for the history hand-over.
  std::swap(mc.previous, mc.contacts);
  std::swap(mc.previousHistory, mc.history);
  mc.contacts.clear();
  const auto ng = static_cast<std::ptrdiff_t>(mc.groups.size());
  // Unit face normals once per step, of the triangles some candidate needs (under a block that is tens
  // of a net's thousands; the others keep stale values nobody reads).
  mc.scratch->faceNormals.resize(walls_.size());
  for (std::size_t m = 0; m < walls_.size(); ++m) {
    const MeshWall& w = walls_[m];
    mc.scratch->faceNormals[m].resize(w.triangles.size());
    if (m >= mc.candidateTriangles.size()) continue;  // no candidates built yet
    for (const std::uint32_t t : mc.candidateTriangles[m]) {
      const auto& tri = w.triangles[t];
      mc.scratch->faceNormals[m][t] = (w.nodes[tri[1]] - w.nodes[tri[0]]).cross(w.nodes[tri[2]] - w.nodes[tri[0]]).normalized();
    }
  }
  SheetTally sheets(walls_.size());
  mc.history.clear();
  if (ng > kParallelMin && omp_get_max_threads() > 1) {
    // Per group, then joined in group order: the same contacts in the same order as one thread.
    mc.scratch->perGroup.resize(mc.groups.size());
    mc.scratch->perGroupHistory.resize(mc.groups.size());
#pragma omp parallel for schedule(dynamic, 16)
    for (std::ptrdiff_t g = 0; g < ng; ++g) {
      const auto gi = static_cast<std::size_t>(g);
      mc.scratch->perGroup[gi].clear();
      mc.scratch->perGroupHistory[gi].clear();
      groupContacts(ctx, mc, walls_, gi, mc.scratch->perGroup[gi], mc.scratch->perGroupHistory[gi], sheets);
    }
    for (std::size_t g = 0; g < mc.scratch->perGroup.size(); ++g) {
      mc.contacts.insert(mc.contacts.end(), mc.scratch->perGroup[g].begin(), mc.scratch->perGroup[g].end());
      mc.history.insert(mc.history.end(), mc.scratch->perGroupHistory[g].begin(), mc.scratch->perGroupHistory[g].end());
    }
  } else {
    // One thread: straight into the contact list (joining thousands of per-group vectors cost as much
    // as finding the contacts).
    for (std::size_t g = 0; g < static_cast<std::size_t>(ng); ++g)
      groupContacts(ctx, mc, walls_, g, mc.contacts, mc.history, sheets);
  }
  for (std::size_t i = 0; i < sheets.lostBy.size(); ++i) {
    MeshWall& w = walls_[i % sheets.meshes];
    w.lostThroughSheet += sheets.lostBy[i];
    w.maxDepthRadii = std::max(w.maxDepthRadii, sheets.deepestBy[i]);
  }

  // Batches per law: contacts are stably ordered by law (usually one law: already in order).
  mc.ranges.assign(ctx.laws.size(), {0, 0});
  if (!std::is_sorted(mc.contacts.begin(), mc.contacts.end(),
                      [](const MeshContact& a, const MeshContact& b) { return a.law < b.law; })) {
    std::vector<std::size_t> order(mc.contacts.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return mc.contacts[a].law < mc.contacts[b].law; });
    std::vector<MeshContact> c2;
    std::vector<ContactHistory> h2;
    for (auto o : order) {
      c2.push_back(mc.contacts[o]);
      h2.push_back(mc.history[o]);
    }
    mc.contacts.swap(c2);
    mc.history.swap(h2);
  }
  for (std::size_t i = 0; i < mc.contacts.size();) {
    std::size_t j = i;
    while (j < mc.contacts.size() && mc.contacts[j].law == mc.contacts[i].law) ++j;
    mc.ranges[static_cast<std::size_t>(mc.contacts[i].law)] = {i, j};
    i = j;
  }
  mc.points.resize(mc.contacts.size());
  for (std::size_t i = 0; i < mc.contacts.size(); ++i) mc.points[i] = mc.contacts[i].point;
  mc.forces.assign(mc.contacts.size(), ContactForce{});
}

void MeshWalls::applyForces(const StepContext& ctx) {
  MeshContacts& mc = contacts_;
  for (auto& w : walls_) {
    std::fill(w.nodeForce.begin(), w.nodeForce.end(), Vec3::Zero());
    w.force.setZero();
    w.moment.setZero();
  }
  double work = 0.0;
  for (std::size_t i = 0; i < mc.contacts.size(); ++i) {
    const MeshContact& c = mc.contacts[i];
    const Vec3& f = mc.forces[i].force;
    ctx.force[c.sphere] += f;
    ctx.torque[c.sphere] += (c.point.point - ctx.centres[c.sphere]).cross(f);
    MeshWall& w = walls_[c.mesh];
    const auto& tri = w.triangles[c.triangle];
    for (int k = 0; k < 3; ++k) w.nodeForce[tri[static_cast<std::size_t>(k)]] -= c.bary[static_cast<std::size_t>(k)] * f;
    w.force -= f;
    w.moment -= c.wallPoint.cross(f);
    work += f.dot(c.wallVelocity);
  }
  power_ = work;
}

void MeshWalls::computeForces(const StepContext& ctx) {
  MeshContacts& mc = contacts_;
  for (std::size_t l = 0; l < ctx.laws.size() && !mc.contacts.empty(); ++l) {
    const auto [begin, end] = mc.ranges[l];
    if (begin == end) continue;
    const std::size_t n = end - begin;
    ctx.laws[l]->compute(std::span(mc.points).subspan(begin, n), std::span(mc.history).subspan(begin, n),
                         std::span(mc.forces).subspan(begin, n), ctx.settings.dt);
  }
  if (!walls_.empty()) applyForces(ctx);
}

void MeshWalls::applyRollingResistance(const StepContext& ctx) {
  MeshContacts& mc = contacts_;
  for (std::size_t i = 0; i < mc.contacts.size(); ++i) {
    const double muR = ctx.laws[static_cast<std::size_t>(mc.contacts[i].law)]->rollingFriction();
    if (muR == 0.0) continue;
    const auto s = mc.contacts[i].sphere;
    const Vec3 m = detail::rollingTorque(mc.points[i].normal, ctx.bodies.angularVelocity[ctx.spheres.body[s]],
                                         mc.points[i].effRadius, ctx.rollingInertia(s), muR, mc.forces[i].normalForce,
                                         ctx.settings.dt, mc.forces[i]);
    ctx.torque[s] += m;
    walls_[mc.contacts[i].mesh].moment -= m;
  }
}

void MeshWalls::move(double dt, double& wallWork) {
  wallWork += power_ * dt;
  for (auto& m : walls_)
    if (m.motion == MeshWall::Motion::kPrescribed)
      for (auto& x : m.nodes) x += m.velocity * dt;
}

void MeshWalls::addStiffness(const std::vector<std::unique_ptr<ContactLaw>>& laws, const Spheres& spheres,
                             BodyStiffness& out) const {
  const MeshContacts& mc = contacts_;
  for (std::size_t i = 0; i < mc.contacts.size(); ++i) {
    const ContactPoint& p = mc.points[i];
    if (!(p.overlap > 0.0)) continue;
    const auto t = laws[static_cast<std::size_t>(mc.contacts[i].law)]->normalTangent(p.effRadius, p.effMass, p.overlap);
    out.add(spheres.body[mc.contacts[i].sphere], t.stiffness, t.damping);
  }
}

}  // namespace dem
