// octovk.Error and one subclass per octovk::ErrorCode, raised for every octovk::Error.
#pragma once

#include <pybind11/pybind11.h>

#include "checked.hpp"

namespace octovk::python {

/// Defines octovk.ErrorCode, octovk.Error and its subclasses in `m`, and translates each
/// octovk::Error thrown through the module into the subclass of its code, with `code`,
/// `message`, `scan` and `detail` attributes.
void bindErrors(pybind11::module_& m);

}  // namespace octovk::python
