// Every class the module binds is read through a caster that refuses an object whose __init__
// never ran (made by T.__new__(T)): pybind11 would hand such an object's raw, unconstructed
// memory to the C++ code as a T, and the interpreter would crash. Included by every source of
// the module before any cast, so that each one sees the same casters.
#pragma once

#include <pybind11/pybind11.h>

#include "octovk/octovk.hpp"
#include "octovk/store.hpp"

namespace octovk::python {

/// Raises TypeError when `src` is an instance of the bound class `type` that holds no C++ object
/// (its __init__ never ran); returns for anything else, which the caster then judges as before.
void requireInitialised(pybind11::handle src, const pybind11::detail::type_info* type);

/// pybind11's caster for a bound class T, with requireInitialised() before every load.
template <class T>
class CheckedCaster : public pybind11::detail::type_caster_base<T> {
 public:
  bool load(pybind11::handle src, bool convert) {
    requireInitialised(src, this->typeinfo);  // found once, when the caster was made
    return pybind11::detail::type_caster_base<T>::load(src, convert);
  }
};

}  // namespace octovk::python

/// Makes pybind11 read bound class T through CheckedCaster (at namespace scope, before any cast
/// of T in the translation unit).
#define OCTOVK_PYTHON_CHECKED_CLASS(T)                               \
  namespace pybind11::detail {                                       \
  template <>                                                        \
  class type_caster<T> : public octovk::python::CheckedCaster<T> {}; \
  }  // namespace pybind11::detail

OCTOVK_PYTHON_CHECKED_CLASS(octovk::Context)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::StoreFollower)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::DeviceInfo)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::Pose)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::StageTimes)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::ScanStats)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::CastRayBackend)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::ScanRays)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::ErrorCode)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::OccupancyMap::DeviceBytes)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::OccupancyMap::CastRayInfo)
