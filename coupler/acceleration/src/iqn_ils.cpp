// IQN-ILS, interface quasi-Newton with an inverse Jacobian from a least-squares model (Degroote,
// Bathe & Vierendeels 2009; the formulation of preCICE, Mehl et al. 2016):
//   V = [Δr_i], W = [ΔH_i] (differences between successive iterations, this window and the last
//   `reusedWindows` converged ones), α = argmin ‖V α + r_k‖ by a QR factorisation whose nearly
//   dependent columns are filtered (|R_ii| < ε ‖v_i‖, the QR1 filter), then x̃_{k+1} = H(x̃_k) + W α.
// The first iteration of the first window (no columns yet) is constant relaxation with ω₀.
#include <algorithm>
#include <deque>
#include <vector>

#include <Eigen/Dense>

#include "accelerations.hpp"

namespace cosim {
namespace {
class IqnIls final : public Acceleration {
 public:
  explicit IqnIls(const AccelerationParams& p) : p_(p) {}
  std::string name() const override { return "iqn_ils"; }

  void next(std::span<const double> x, std::span<const double> hx, std::span<double> out) override {
    const auto n = static_cast<Eigen::Index>(x.size());
    Eigen::Map<const Eigen::VectorXd> xv(x.data(), n), hv(hx.data(), n);
    Eigen::VectorXd r = hv - xv;
    if (hasLast_ && lastR_.size() == n) {
      current_.push_back({r - lastR_, hv - lastH_});
    }
    lastR_ = r;
    lastH_ = hv;
    hasLast_ = true;
    // Columns: this window's newest first, then the reused windows'.
    std::vector<const Column*> cols;
    for (auto it = current_.rbegin(); it != current_.rend(); ++it) cols.push_back(&*it);
    for (const auto& w : reused_)
      for (auto it = w.rbegin(); it != w.rend(); ++it) cols.push_back(&*it);
    if (static_cast<int>(cols.size()) > p_.maxColumns) cols.resize(static_cast<std::size_t>(p_.maxColumns));
    if (cols.empty()) {
      Eigen::Map<Eigen::VectorXd>(out.data(), n) = xv + p_.relaxation * r;
      return;
    }
    // QR1 filter: build Q column by column (modified Gram–Schmidt), dropping dependent columns.
    std::vector<const Column*> kept;
    Eigen::MatrixXd Q(n, 0);
    for (const Column* c : cols) {
      Eigen::VectorXd v = c->dr;
      const double norm0 = v.norm();
      for (Eigen::Index j = 0; j < Q.cols(); ++j) v -= Q.col(j).dot(v) * Q.col(j);
      if (norm0 == 0.0 || v.norm() < p_.filter * norm0) continue;
      Q.conservativeResize(n, Q.cols() + 1);
      Q.col(Q.cols() - 1) = v.normalized();
      kept.push_back(c);
    }
    if (kept.empty()) {
      Eigen::Map<Eigen::VectorXd>(out.data(), n) = xv + p_.relaxation * r;
      return;
    }
    Eigen::MatrixXd V(n, static_cast<Eigen::Index>(kept.size())), W(n, static_cast<Eigen::Index>(kept.size()));
    for (std::size_t j = 0; j < kept.size(); ++j) {
      V.col(static_cast<Eigen::Index>(j)) = kept[j]->dr;
      W.col(static_cast<Eigen::Index>(j)) = kept[j]->dh;
    }
    const Eigen::VectorXd alpha = V.colPivHouseholderQr().solve(-r);
    Eigen::Map<Eigen::VectorXd>(out.data(), n) = hv + W * alpha;
  }

  void converged() override {
    if (!current_.empty()) reused_.push_front(std::move(current_));
    while (static_cast<int>(reused_.size()) > p_.reusedWindows) reused_.pop_back();
    current_.clear();
    hasLast_ = false;
  }

 private:
  struct Column {
    Eigen::VectorXd dr, dh;
  };
  AccelerationParams p_;
  std::vector<Column> current_;
  std::deque<std::vector<Column>> reused_;
  Eigen::VectorXd lastR_, lastH_;
  bool hasLast_ = false;
};
}  // namespace

std::unique_ptr<Acceleration> makeIqnIls(const AccelerationParams& p) { return std::make_unique<IqnIls>(p); }
}  // namespace cosim
