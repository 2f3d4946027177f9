// What every friction model provides, checked at compile time.
//
// A model is a class template on its scalar with
//   using Scalar = T;
//   void reset();                       // virgin state
//   T step(const Motion<T>&) noexcept;  // advance one sample, return the friction force [N]
// The force follows the sign convention of methods.md: it resists the motion as the drive sees
// it, so F * v >= 0 while sliding.
#pragma once

#include <concepts>

#include "friction/motion.hpp"

namespace friction {

template <class M>
concept FrictionModel = requires(M m, const Motion<typename M::Scalar>& motion) {
  typename M::Scalar;
  { m.step(motion) } -> std::convertible_to<typename M::Scalar>;
  m.reset();
};

}  // namespace friction
