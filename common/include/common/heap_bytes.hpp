#pragma once
// What a structure holds on the heap, for the memory tables of a run's summary (`cost:`): a vector counts
// its capacity, not its size, since that is what the allocator gave it; a vector of vectors (or of
// anything else that owns memory) adds its elements' own. A type with a member `std::size_t heapBytes()
// const` reports itself.
//
//   std::size_t SpherePairs::heapBytes() const { return common::heapBytes(contacts_, work_->spare); }

#include <cstddef>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

namespace common {

template <class T>
std::size_t heapBytes(const T& value) {
  if constexpr (requires { value.heapBytes(); })
    return value.heapBytes();
  else
    return 0;  // a scalar, a fixed-size struct: nothing on the heap
}

template <class T, class A>
std::size_t heapBytes(const std::vector<T, A>& v) {
  std::size_t n = v.capacity() * sizeof(T);
  if constexpr (!std::is_trivially_copyable_v<T>)
    for (const auto& x : v) n += heapBytes(x);
  return n;
}

template <class T>
std::size_t heapBytes(const std::unique_ptr<T>& p) {
  return p ? sizeof(T) + heapBytes(*p) : 0;
}

template <class A, class B>
std::size_t heapBytes(const std::pair<A, B>& p) {
  return heapBytes(p.first) + heapBytes(p.second);
}

template <class A, class B, class... Rest>
std::size_t heapBytes(const A& a, const B& b, const Rest&... rest) {
  return heapBytes(a) + heapBytes(b) + (std::size_t{0} + ... + heapBytes(rest));
}

}  // namespace common
