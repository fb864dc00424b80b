#include "errors.hpp"

#include <array>
#include <string>
#include <utility>

#include "octovk/errors.hpp"

namespace octovk::python {
namespace py = pybind11;
namespace {

struct ErrorClass {
  ErrorCode code;
  const char* enum_name;
  const char* class_name;
  PyObject* mixin;  // a built-in exception the class also derives from, or nullptr
  const char* doc;
};

// Built when the module loads (the built-in exception objects exist only once Python runs).
std::array<ErrorClass, 9> errorClasses() {
  return {{
      {ErrorCode::kNoDevice, "NO_DEVICE", "NoDeviceError", nullptr,
       "No usable Vulkan device (install mesa-vulkan-drivers for the CPU device)."},
      {ErrorCode::kMissingFeature, "MISSING_FEATURE", "MissingFeatureError", nullptr,
       "The device lacks a feature octovk needs; the message names it."},
      {ErrorCode::kInvalidArgument, "INVALID_ARGUMENT", "InvalidArgumentError", PyExc_ValueError,
       "A parameter or input is out of its domain (also a ValueError)."},
      {ErrorCode::kOutOfDeviceMemory, "OUT_OF_DEVICE_MEMORY", "OutOfDeviceMemoryError",
       PyExc_MemoryError,
       "The device (or max_device_bytes) could not hold the map; the map is as before the call "
       "(also a MemoryError)."},
      {ErrorCode::kVulkan, "VULKAN", "VulkanError", nullptr,
       "An unexpected Vulkan failure, said in words; detail names the driver call and its "
       "VkResult."},
      {ErrorCode::kIo, "IO", "IoError", PyExc_OSError,
       "A file could not be read or written (also an OSError)."},
      {ErrorCode::kFormat, "FORMAT", "FormatError", nullptr,
       "A file is not in the expected format; the message names the file and the fault."},
      {ErrorCode::kOutOfHostMemory, "OUT_OF_HOST_MEMORY", "OutOfHostMemoryError", PyExc_MemoryError,
       "The host could not allocate memory; the map is as before the call (also a MemoryError)."},
      {ErrorCode::kInternal, "INTERNAL", "InternalError", nullptr,
       "octovk broke one of its own invariants: a bug, to be reported with the input."},
  }};
}

static_assert(static_cast<int>(ErrorCode::kInternal) == 8,
              "a new octovk::ErrorCode needs its Python class in errorClasses() (and octovk.pyi)");

// The classes, indexed by ErrorCode; owned by the module (kept alive by its attributes).
std::array<PyObject*, 9> g_classes{};
PyObject* g_code_enum = nullptr;

// The library's message in the module's words: its C++ names of what a Python caller sets or
// calls (the Map's max_device_bytes argument, Map.trim()).
std::string inPythonWords(std::string message) {
  static const std::array<std::pair<const char*, const char*>, 3> kNames{{
      {"MapParams::max_device_bytes", "the Map's max_device_bytes"},
      {"OccupancyMap::trim()", "Map.trim()"},
      {"DistanceField::", "DistanceField."},
  }};
  for (const auto& [from, to] : kNames) {
    const std::string f(from), t(to);
    for (std::size_t at = message.find(f); at != std::string::npos;
         at = message.find(f, at + t.size()))
      message.replace(at, f.size(), t);
  }
  return message;
}

}  // namespace

void bindErrors(py::module_& m) {
  py::enum_<ErrorCode> codes(m, "ErrorCode",
                             "What went wrong, coarsely (octovk::ErrorCode): Error.code.");
  for (const ErrorClass& c : errorClasses()) codes.value(c.enum_name, c.code);
  g_code_enum = codes.ptr();

  PyObject* base = PyErr_NewExceptionWithDoc(
      "octovk.Error",
      "An error of the octovk library. Attributes: code (octovk.ErrorCode), message (the "
      "library's message: what failed, why and the fix), scan (for an error found by a "
      "synchronisation in a scan submitted earlier, that scan's ticket; else 0) and detail "
      "(for developers: the Vulkan call that failed, its VkResult and the source place, or ''; "
      "part of the message only when OCTOVK_DEBUG is set). Each code has its subclass "
      "(NoDeviceError, InvalidArgumentError, ...).",
      PyExc_RuntimeError, nullptr);
  if (!base) throw py::error_already_set();
  m.add_object("Error", py::reinterpret_steal<py::object>(base));
  for (const ErrorClass& c : errorClasses()) {
    py::tuple bases = c.mixin ? py::make_tuple(py::handle(base), py::handle(c.mixin))
                              : py::make_tuple(py::handle(base));
    const std::string name = std::string("octovk.") + c.class_name;
    PyObject* cls = PyErr_NewExceptionWithDoc(name.c_str(), c.doc, bases.ptr(), nullptr);
    if (!cls) throw py::error_already_set();
    m.add_object(c.class_name, py::reinterpret_steal<py::object>(cls));
    g_classes[static_cast<std::size_t>(c.code)] = cls;
  }

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
      const auto index = static_cast<std::size_t>(e.code());
      PyObject* cls = index < g_classes.size() ? g_classes[index] : g_classes.back();
      const std::string message = inPythonWords(e.what());
      py::object error =
          py::reinterpret_steal<py::object>(PyObject_CallFunction(cls, "s", message.c_str()));
      if (!error) return;  // the call set its own Python error
      error.attr("code") = py::handle(g_code_enum)(static_cast<int>(e.code()));
      error.attr("message") = py::str(message);
      error.attr("scan") = py::int_(e.scan());
      error.attr("detail") = py::str(e.detail());
      PyErr_SetObject(cls, error.ptr());
    }
  });
}

}  // namespace octovk::python
