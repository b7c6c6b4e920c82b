#pragma once
// The batch loop every contact law shares: Derived supplies only `pairForce` for one open contact, the
// loop (OpenMP, zero force and reset history for open contacts) is written once and inlined per law.
#include "dem/contact_law.hpp"

namespace dem::detail {

template <class Derived>
class BatchLaw : public ContactLaw {
 public:
  void compute(std::span<const ContactPoint> points, std::span<ContactHistory> history, std::span<ContactForce> out,
               double dt) const final {
    const auto& law = static_cast<const Derived&>(*this);
    const auto n = static_cast<std::ptrdiff_t>(points.size());
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (std::ptrdiff_t i = 0; i < n; ++i) {
      const ContactPoint& p = points[i];
      ContactHistory& h = history[i];
      ContactForce& f = out[i];
      f = ContactForce{};
      if (p.overlap <= 0.0) {
        h = ContactHistory{};
        continue;
      }
      law.pairForce(p, h, f, dt);
      h.lastOverlap = p.overlap;
    }
  }
};

}  // namespace dem::detail
