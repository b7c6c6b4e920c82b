#pragma once
// One registration mechanism for every pluggable kind (contact laws, FEM elements, lattice rod laws and
// solvers, mappings, accelerations; CONTRIBUTING.md, "Adding one unit of physics"): an explicit table of
// entries, each with its `name` (the scene's `type:`, equal to the file name) and whatever builds it,
// and this view over the table. A static library drops self-registering objects, so the table's line is
// the one registration a new unit needs. Entries read their own keys: a key of another type stays unread
// and is an unknown-key error (exit 2).
//
//   const Entry kMappings[] = {{"identity", makeIdentity}, {"nearest_neighbor", makeNearestNeighbor}};
//   constexpr common::Registry<Entry> kRegistry{kMappings, "mapping"};
//   kRegistry.at(name).make(from, to);

#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace common {

template <class Entry>
class Registry {
 public:
  /// `kind` names what the entries are, for messages ("mapping", "contact law").
  constexpr Registry(std::span<const Entry> entries, const char* kind) : entries_(entries), kind_(kind) {}

  std::vector<std::string> names() const {
    std::vector<std::string> out;
    for (const Entry& e : entries_) out.emplace_back(e.name);
    return out;
  }
  const Entry* find(std::string_view name) const {
    for (const Entry& e : entries_)
      if (name == e.name) return &e;
    return nullptr;
  }
  /// The entry named `name`; std::invalid_argument listing the registered ones otherwise (a scene's
  /// reader has checked the name with Config::choice(…, names()) before, with its location).
  const Entry& at(std::string_view name) const {
    if (const Entry* e = find(name)) return *e;
    throw std::invalid_argument(fmt::format("unknown {} \"{}\" (registered: {})", kind_, name, fmt::join(names(), ", ")));
  }
  std::span<const Entry> entries() const { return entries_; }

 private:
  std::span<const Entry> entries_;
  const char* kind_;
};

}  // namespace common
