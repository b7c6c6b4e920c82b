#pragma once
// One object per OpenMP thread, each on cache lines of its own. Threads that keep neighbouring objects in
// one line (a running sum stored back after each block, a vector whose end pointer moves with every
// push_back) pass that line between their cores at each update, and more often the more threads share it.
#include <cstddef>
#include <vector>

#include "common/heap_bytes.hpp"

namespace dem::detail {

// Two lines: some CPUs fetch lines in adjacent pairs, so neighbours 64 bytes apart can still collide.
inline constexpr std::size_t kFalseSharingRange = 128;

template <class T>
class PerThread {
 public:
  PerThread() = default;
  explicit PerThread(std::size_t threads, const T& initial = T{}) : slots_(threads, Slot{initial}) {}
  void resize(std::size_t threads) { slots_.resize(threads); }

  T& operator[](std::size_t t) { return slots_[t].value; }
  const T& operator[](std::size_t t) const { return slots_[t].value; }
  std::size_t size() const { return slots_.size(); }
  std::size_t heapBytes() const {
    std::size_t n = slots_.capacity() * sizeof(Slot);
    for (const Slot& s : slots_) n += common::heapBytes(s.value);
    return n;
  }
  // The slots in thread order (the order results are combined in, for the same bits on any threads).
  template <class Visit>
  void forEach(Visit&& visit) {
    for (Slot& s : slots_) visit(s.value);
  }
  template <class Visit>
  void forEach(Visit&& visit) const {
    for (const Slot& s : slots_) visit(s.value);
  }

 private:
  struct alignas(kFalseSharingRange) Slot {
    T value;
  };
  std::vector<Slot> slots_;
};

}  // namespace dem::detail
