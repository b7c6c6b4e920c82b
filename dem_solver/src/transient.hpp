#pragma once
// Derived data and work space a component of dem::Simulation keeps from call to call but that is not its
// state: a copy of the component (a checkpoint, copied at every coupling window) starts with it empty, and
// assigning a copy back keeps the destination's own. What it holds must follow from the state and the
// scene, or be rewritten before it is read.
namespace dem::detail {

template <class T>
struct Transient {
  T value{};
  Transient() = default;
  Transient(const Transient&) {}
  Transient& operator=(const Transient&) { return *this; }
  T* operator->() { return &value; }
  const T* operator->() const { return &value; }
  T& operator*() { return value; }
  const T& operator*() const { return value; }
};

}  // namespace dem::detail
