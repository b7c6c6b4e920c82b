#pragma once
// The materials of a scene and the contact law of each pair of them: what a contact, a bond or a time-step
// estimate reads to find its law. A component of dem::Simulation (Simulation::interactions()), filled while
// the scene is built, read-only once it runs.

#include <cstdint>
#include <memory>
#include <vector>

#include "dem/contact_law.hpp"
#include "dem/material.hpp"

namespace dem {

class Interactions {
 public:
  /// Returns the material's index.
  std::uint32_t addMaterial(const Material& m);
  const std::vector<Material>& materials() const { return materials_; }
  /// The law for materials (a, b), symmetric.
  void set(std::uint32_t a, std::uint32_t b, std::unique_ptr<ContactLaw> law);
  /// The law of materials (a, b); nullptr where they do not interact.
  const ContactLaw* law(std::uint32_t a, std::uint32_t b) const {
    const int i = table_[a * materials_.size() + b];
    return i < 0 ? nullptr : laws_[static_cast<std::size_t>(i)].get();
  }
  /// The bonding side of the law of materials (a, b); nullptr where it does not bond.
  const BondingLaw* bonding(std::uint32_t a, std::uint32_t b) const {
    const ContactLaw* l = law(a, b);
    return l ? l->bonding() : nullptr;
  }
  /// Every law set, each once.
  const std::vector<std::unique_ptr<ContactLaw>>& laws() const { return laws_; }
  /// materials × materials → index in laws(), −1: none (the step's per-contact lookup).
  const std::vector<int>& table() const { return table_; }

  /// A law as a number that outlives the process (a checkpoint): its index in laws(), −1 for none; and
  /// back (nullptr for an index out of range).
  int indexOf(const ContactLaw* law) const;
  const ContactLaw* at(int index) const;
  /// Whether some law bonds spheres (its bonds may form later, by Simulation::formBonds()).
  bool anyBonding() const;
  /// Whether some law has Coulomb friction, or rolling resistance.
  bool anyFriction() const;
  bool anyRolling() const;

  std::size_t heapBytes() const;

 private:
  std::vector<Material> materials_;
  std::vector<std::unique_ptr<ContactLaw>> laws_;
  std::vector<int> table_;
};

}  // namespace dem
