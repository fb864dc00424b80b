#include "checked.hpp"

#include <string>

namespace octovk::python {

namespace py = pybind11;

void requireInitialised(py::handle src, const py::detail::type_info* info) {
  if (!info || !src || !PyObject_TypeCheck(src.ptr(), info->type)) return;
  auto* instance = reinterpret_cast<py::detail::instance*>(src.ptr());
  py::detail::value_and_holder held =
      instance->get_value_and_holder(info, /*throw_if_missing=*/false);
  // An instance of a bound subclass (a ColorMap seen as a Map) holds its value under its own
  // type: pybind11 loads that one.
  if (held.vh == nullptr) held = instance->get_value_and_holder(nullptr, false);
  // Only __init__ (or the module returning an object) sets the value; a load would otherwise
  // allocate raw memory for it and call the methods on that.
  if (held.vh == nullptr || held.value_ptr() != nullptr) return;
  const std::string name = Py_TYPE(src.ptr())->tp_name;
  throw py::type_error("this " + name +
                       " object was never initialised: it was made by __new__ and its __init__ "
                       "never ran; use one made by calling the class or returned by octovk");
}

}  // namespace octovk::python
