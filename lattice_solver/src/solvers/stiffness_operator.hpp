#pragma once
// K of a Model as an Eigen matrix-free operator, so Eigen's ConjugateGradient runs on either the
// assembled or the matrix-free stiffness (Eigen's "matrix-free solvers" pattern: an EigenBase type
// and a generic_product_impl that calls Model::apply).
#include <type_traits>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "lattice/model.hpp"

namespace lattice {
class StiffnessOperator;
}

namespace Eigen::internal {
template <>
struct traits<lattice::StiffnessOperator> : public Eigen::internal::traits<Eigen::SparseMatrix<double>> {};
}  // namespace Eigen::internal

namespace lattice {

class StiffnessOperator : public Eigen::EigenBase<StiffnessOperator> {
 public:
  using Scalar = double;
  using RealScalar = double;
  using StorageIndex = int;
  enum { ColsAtCompileTime = Eigen::Dynamic, MaxColsAtCompileTime = Eigen::Dynamic, IsRowMajor = false };

  Eigen::Index rows() const { return static_cast<Eigen::Index>(model_->freeDofs()); }
  Eigen::Index cols() const { return rows(); }
  template <typename Rhs>
  Eigen::Product<StiffnessOperator, Rhs, Eigen::AliasFreeProduct> operator*(const Eigen::MatrixBase<Rhs>& x) const {
    return Eigen::Product<StiffnessOperator, Rhs, Eigen::AliasFreeProduct>(*this, x.derived());
  }
  void attach(const Model& model) { model_ = &model; }
  const Model& model() const { return *model_; }

 private:
  const Model* model_ = nullptr;
};

}  // namespace lattice

namespace Eigen::internal {
template <typename Rhs>
struct generic_product_impl<lattice::StiffnessOperator, Rhs, SparseShape, DenseShape, GemvProduct>
    : generic_product_impl_base<lattice::StiffnessOperator, Rhs,
                                generic_product_impl<lattice::StiffnessOperator, Rhs>> {
  // y = K x straight into the destination: cg's product needs no copy of x, zeroing of y or extra sum.
  template <typename Dest>
  static void evalTo(Dest& dst, const lattice::StiffnessOperator& lhs, const Rhs& rhs) {
    if constexpr (std::is_same_v<Dest, Eigen::VectorXd> && std::is_same_v<std::decay_t<Rhs>, Eigen::VectorXd>) {
      lhs.model().apply(rhs, dst);
    } else {
      dst.setZero();
      scaleAndAddTo(dst, lhs, rhs, 1.0);
    }
  }
  template <typename Dest>
  static void scaleAndAddTo(Dest& dst, const lattice::StiffnessOperator& lhs, const Rhs& rhs, const double& alpha) {
    const Eigen::VectorXd x = rhs;
    Eigen::VectorXd y;
    lhs.model().apply(x, y);
    dst += alpha * y;
  }
};
}  // namespace Eigen::internal
