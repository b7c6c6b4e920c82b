#pragma once
// The element interface (CONTRIBUTING.md, "Adding one unit of physics"). An Element object is a block of
// elements of one type and one material; every call loops over the whole block inside, so there is no
// virtual call per element.
//
// Per-element results are written to per-element slots (nodesPerElement × 3 values each) and summed per
// node afterwards by the model in a fixed order: no data race, deterministic for a thread count.
// Units SI. Elements receive displacements u from their reference configuration (flat, 3 per node), not
// positions: strains computed from X + u lose digits to cancellation (1e-9 relative residual floors).

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>

#include "common/h5_writer.hpp"

namespace fem {

using Vec3 = Eigen::Vector3d;
using Triplet = Eigen::Triplet<double>;

class Element {
 public:
  virtual ~Element() = default;
  /// The registered name, equal to the file name (`membrane_tri3`).
  virtual std::string name() const = 0;
  virtual int nodesPerElement() const = 0;
  /// How its cells are written to the results (the XDMF topology ParaView draws).
  virtual common::CellType cellType() const = 0;
  /// Node indices, nodesPerElement() per element.
  virtual const std::vector<std::uint32_t>& connectivity() const = 0;
  std::size_t size() const { return connectivity().size() / static_cast<std::size_t>(nodesPerElement()); }

  /// Internal forces of every element into `slots` (size() × nodesPerElement() × 3), returns the strain
  /// energy of the block [J].
  virtual double internalForces(std::span<const double> u, std::span<double> slots) const = 0;
  /// Tangent stiffness (material + geometric) as triplets on global dof indices 3 n + k.
  virtual void tangent(std::span<const double> u, std::vector<Triplet>& triplets) const = 0;
  /// Lumped mass added per node [kg].
  virtual void addLumpedMass(std::span<double> nodeMass) const = 0;
  /// Per element: the largest stable explicit step (lumped mass, central differences) [s], in the
  /// reference configuration.
  virtual double criticalTimeStep() const = 0;
  /// The block in the configuration u: the largest stable step now (a stretched membrane or cable is
  /// stiffer, and a prestressed one carries faster waves), and its most compressed element with its
  /// Jacobian (tet4: det F, the volume ratio, ≤ 0 when inverted; membrane: the area ratio; truss: the
  /// stretch).
  struct Current {
    double criticalTimeStep = 0.0;  ///< [s]
    std::size_t element = 0;        ///< the element of smallest jacobian
    double jacobian = 1.0;          ///< [-]
  };
  virtual Current current(std::span<const double> u) const = 0;
  /// Stress per element for output: components() values each (membrane: PK2 S11 S22 S12 [Pa]; truss:
  /// axial force [N]).
  virtual int stressComponents() const = 0;
  virtual void stress(std::span<const double> u, std::span<double> out) const = 0;
  /// Dead pressure load on the reference area, per node [N]: q (reference area) along `direction`.
  /// Only surface elements implement it.
  virtual void addPressure(double q, const Vec3& direction, std::span<double> force) const;

  /// Capabilities (small extra interfaces), asked for by what they are, never by the element's type.
  virtual class Prestressed* prestressed() { return nullptr; }
  const Prestressed* prestressed() const { return const_cast<Element*>(this)->prestressed(); }

  /// A bridging domain's energy weights (fem/bridging.hpp): per element, the share α_e of its energy the
  /// continuum carries; its internal forces, strain energy and lumped mass are scaled by it (empty: 1).
  /// Explicit runs only: the tangent is not weighted.
  void setWeights(std::vector<double> w) { weights_ = std::move(w); }
  const std::vector<double>& weights() const { return weights_; }

 protected:
  double weight(std::size_t e) const { return weights_.empty() ? 1.0 : weights_[e]; }

 private:
  std::vector<double> weights_;
};

/// An element with an in-plane prestress [Pa] a static solve may raise and lower (prestress
/// continuation): membranes.
class Prestressed {
 public:
  virtual ~Prestressed() = default;
  virtual double prestress() const = 0;
  virtual void setPrestress(double s) = 0;
};

}  // namespace fem
