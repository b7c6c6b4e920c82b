#include "dem/interactions.hpp"

#include <algorithm>

#include "common/errors.hpp"
#include "common/heap_bytes.hpp"

namespace dem {

std::uint32_t Interactions::addMaterial(const Material& m) {
  const auto n = materials_.size();
  std::vector<int> grown((n + 1) * (n + 1), -1);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) grown[i * (n + 1) + j] = table_[i * n + j];
  table_ = std::move(grown);
  materials_.push_back(m);
  return static_cast<std::uint32_t>(n);
}

void Interactions::set(std::uint32_t a, std::uint32_t b, std::unique_ptr<ContactLaw> law) {
  const auto n = materials_.size();
  COSIM_ASSERT(a < n && b < n, "material index {} or {} out of range ({})", a, b, n);
  laws_.push_back(std::move(law));
  table_[a * n + b] = table_[b * n + a] = static_cast<int>(laws_.size() - 1);
}

int Interactions::indexOf(const ContactLaw* law) const {
  for (std::size_t i = 0; i < laws_.size(); ++i)
    if (laws_[i].get() == law) return static_cast<int>(i);
  return -1;
}

const ContactLaw* Interactions::at(int index) const {
  return index < 0 || static_cast<std::size_t>(index) >= laws_.size() ? nullptr : laws_[static_cast<std::size_t>(index)].get();
}

bool Interactions::anyBonding() const {
  return std::any_of(laws_.begin(), laws_.end(), [](const auto& l) { return l->bonding() != nullptr; });
}

bool Interactions::anyFriction() const {
  return std::any_of(laws_.begin(), laws_.end(), [](const auto& l) { return l->friction() > 0.0; });
}

bool Interactions::anyRolling() const {
  return std::any_of(laws_.begin(), laws_.end(), [](const auto& l) { return l->rollingFriction() > 0.0; });
}

std::size_t Interactions::heapBytes() const { return common::heapBytes(materials_, table_); }

}  // namespace dem
