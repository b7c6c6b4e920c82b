// IQN-ILS, interface quasi-Newton with an inverse Jacobian from a least-squares model (Degroote,
// Bathe & Vierendeels 2009; the formulation of preCICE, Mehl et al. 2016):
//   V = [Δr_i], W = [ΔH_i] (differences between successive iterations, this window and the last
//   `reusedWindows` converged ones), α = argmin ‖P (V α + r_k)‖ (P the diagonal of setWeights, the
//   identity without; W is not weighted: x̃ moves in its own units) by a QR factorisation whose nearly
//   dependent columns are filtered (`filter_type`, cosim/qr_filter.hpp), then x̃_{k+1} = H(x̃_k) + W α.
// The first iteration of the first window (no columns yet) is constant relaxation with ω₀.
// A changing active set (`active_set`; entries where H(x̃) is exactly zero are inactive: a node out of
// contact gets no force): `keep` uses the columns as they are; `mask` leaves the inactive entries out
// of V and W, so a column learnt while a node was in contact neither steers the fit nor puts a force
// back on that node once it has left; `drop` forgets every column when the set changes, as a restart.
#include <algorithm>
#include <deque>
#include <vector>

#include <Eigen/Dense>

#include <fmt/format.h>

#include "accelerations.hpp"
#include "cosim/qr_filter.hpp"
#include "common/state_archive.hpp"

namespace cosim {
namespace {

/// Its keys of `coupling.acceleration`, and the relaxation ω of its first step.
struct Settings {
  double relaxation = 0.5;
  int reusedWindows = 8;  ///< windows whose columns are reused
  int maxColumns = 100;   ///< columns kept at most
  double filter = 1e-4;   ///< the QR filter's limit (cosim/qr_filter.hpp)
  QrFilter filterType = QrFilter::kQr2;
  /// Across a changing active set (the entries where H(x̃) is not exactly zero: the nodes in contact of a
  /// force field): keep every column as it is, mask the columns to the entries active now, or drop every
  /// column when the set changes.
  enum class ActiveSet { kKeep, kMask, kDrop } activeSet = ActiveSet::kKeep;
};

class IqnIls final : public Acceleration {
 public:
  explicit IqnIls(const Settings& p) : p_(p) {}
  std::string name() const override { return "iqn_ils"; }

  void next(std::span<const double> x, std::span<const double> hx, std::span<double> out) override {
    const auto n = static_cast<Eigen::Index>(x.size());
    Eigen::Map<const Eigen::VectorXd> xv(x.data(), n), hv(hx.data(), n);
    using ActiveSet = Settings::ActiveSet;
    if (p_.activeSet != ActiveSet::kKeep) {
      active_.resize(n);
      bool changed = lastActive_.size() != n;
      for (Eigen::Index i = 0; i < n; ++i) {
        const double a = hv(i) != 0.0 ? 1.0 : 0.0;
        changed = changed || lastActive_(i) != a;
        active_(i) = a;
      }
      if (changed && p_.activeSet == ActiveSet::kDrop && lastActive_.size() == n) {
        current_.clear();
        reused_.clear();
        hasLast_ = false;
      }
      lastActive_ = active_;
    }
    const bool masked = p_.activeSet == ActiveSet::kMask;
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
    // A reused window of another length (adaptive windows) models another interface Jacobian: left out.
    for (const auto& w : reused_)
      if (w.dt == windowSize_)
        for (auto it = w.columns.rbegin(); it != w.columns.rend(); ++it) cols.push_back(&*it);
    if (static_cast<int>(cols.size()) > p_.maxColumns) cols.resize(static_cast<std::size_t>(p_.maxColumns));
    if (cols.empty()) {
      Eigen::Map<Eigen::VectorXd>(out.data(), n) = xv + p_.relaxation * r;
      return;
    }
    // V = Q R with the filter (cosim/qr_filter.hpp), then α = R⁻¹ Qᵀ(−r).
    const bool weighted = weights_.size() == x.size();
    const Eigen::Map<const Eigen::VectorXd> w(weighted ? weights_.data() : nullptr, weighted ? n : 0);
    if (masked) scale_ = weighted ? Eigen::VectorXd(w.cwiseProduct(active_)) : active_;
    const std::vector<std::size_t> which = filteredQr(
        cols.size(), n,
        [&](std::size_t i, Eigen::VectorXd& v) {
          if (masked) v = scale_.cwiseProduct(cols[i]->dr);
          else if (weighted) v = w.cwiseProduct(cols[i]->dr);
          else v = cols[i]->dr;
        },
        p_.filterType, p_.filter, Q_, R_);
    const auto k = static_cast<Eigen::Index>(which.size());
    if (k == 0) {
      Eigen::Map<Eigen::VectorXd>(out.data(), n) = xv + p_.relaxation * r;
      return;
    }
    if (masked) r = scale_.cwiseProduct(r);
    else if (weighted) r = w.cwiseProduct(r);
    const Eigen::VectorXd alpha = R_.triangularView<Eigen::Upper>().solve(-(Q_.leftCols(k).transpose() * r));
    Eigen::Map<Eigen::VectorXd> next(out.data(), n);
    next = hv;
    for (Eigen::Index j = 0; j < k; ++j) {
      const Eigen::VectorXd& dh = cols[which[static_cast<std::size_t>(j)]]->dh;
      if (masked) next += alpha(j) * active_.cwiseProduct(dh);
      else next += alpha(j) * dh;
    }
  }

  void abandon() override {
    current_.clear();
    hasLast_ = false;
  }

  void unconverged() override {
    reused_.clear();
    current_.clear();
    hasLast_ = false;
  }

  void converged() override {
    if (!current_.empty()) reused_.push_front({windowSize_, std::move(current_)});
    while (static_cast<int>(reused_.size()) > p_.reusedWindows) reused_.pop_back();
    current_.clear();
    hasLast_ = false;
  }

  // Between windows only the reused windows' columns remain (converged() closed the current one).
  void archive(common::StateArchive& a) override {
    if (p_.activeSet != Settings::ActiveSet::kKeep) vector(a, "last_active", lastActive_);
    std::uint64_t windows = reused_.size();
    a.io("reused_windows", windows);
    if (a.reading()) reused_.assign(windows, {});
    for (std::size_t w = 0; w < reused_.size(); ++w) {
      auto scope = a.scope(fmt::format("window_{}", w));
      a.io("dt", reused_[w].dt);
      std::uint64_t columns = reused_[w].columns.size();
      a.io("columns", columns);
      if (a.reading()) reused_[w].columns.resize(columns);
      for (std::size_t c = 0; c < reused_[w].columns.size(); ++c) {
        vector(a, fmt::format("dr_{}", c), reused_[w].columns[c].dr);
        vector(a, fmt::format("dh_{}", c), reused_[w].columns[c].dh);
      }
    }
  }

 private:
  static void vector(common::StateArchive& a, const std::string& name, Eigen::VectorXd& v) {
    std::vector<double> values(v.data(), v.data() + v.size());
    a.io(name, values);
    if (a.reading()) v = Eigen::Map<const Eigen::VectorXd>(values.data(), static_cast<Eigen::Index>(values.size()));
  }
  struct Column {
    Eigen::VectorXd dr, dh;
  };
  Settings p_;
  std::vector<Column> current_;
  struct Window {
    double dt = 0.0;  // its length [s]
    std::vector<Column> columns;
  };
  std::deque<Window> reused_;
  Eigen::VectorXd lastR_, lastH_;
  bool hasLast_ = false;
  Eigen::MatrixXd Q_, R_;  // scratch, kept between calls to avoid reallocation
  Eigen::VectorXd active_, lastActive_, scale_;  // active_set: 1 where H(x̃) ≠ 0, this call and the last
};
}  // namespace

AccelerationMake readIqnIls(const common::Config& c) {
  Settings p;
  p.reusedWindows = c.get<int>("reused_windows", p.reusedWindows);
  p.maxColumns = c.get<int>("max_columns", p.maxColumns);
  p.filter = c.get("filter", p.filter, common::Interval::positive());
  p.filterType = qrFilterNamed(c.choice("filter_type", qrFilterNames(), "qr2"));
  const std::string active = c.choice("active_set", {"keep", "mask", "drop"}, "keep");
  p.activeSet = active == "mask"   ? Settings::ActiveSet::kMask
                : active == "drop" ? Settings::ActiveSet::kDrop
                                   : Settings::ActiveSet::kKeep;
  return [p](double relaxation) {
    Settings withRelaxation = p;
    withRelaxation.relaxation = relaxation;
    return std::make_unique<IqnIls>(withRelaxation);
  };
}
}  // namespace cosim
