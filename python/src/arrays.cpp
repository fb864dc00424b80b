#include "arrays.hpp"

#include <dlpack/dlpack.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <optional>
#include <sstream>

namespace octovk::python {

struct Element {
  char kind = '?';  // 'f' float, 'i' signed, 'u' unsigned, 'b' bool, 'c' complex, 0 other
  std::size_t bytes = 0;
  bool foreign_order = false;  // not the host's byte order
  std::string other;           // the raw description when kind == 0
};

namespace {

std::atomic<std::uintptr_t> g_last_input{0};

std::string elementName(const Element& e) {
  if (e.kind == 0) return e.other;
  std::string name;
  switch (e.kind) {
    case 'f':
      name = "float";
      break;
    case 'i':
      name = "int";
      break;
    case 'u':
      name = "uint";
      break;
    case 'c':
      name = "complex";
      break;
    default:
      name = "bool";
      break;
  }
  if (e.kind != 'b') name += std::to_string(8 * e.bytes);
  if (e.foreign_order) name = "byte-swapped " + name;
  return name;
}

const char* dtypeName(DType t) {
  switch (t) {
    case DType::kFloat32:
      return "float32";
    case DType::kUint16:
      return "uint16";
    default:
      return "uint8";
  }
}

std::size_t dtypeBytes(DType t) {
  switch (t) {
    case DType::kFloat32:
      return 4;
    case DType::kUint16:
      return 2;
    default:
      return 1;
  }
}

bool matches(const Element& e, DType t) {
  if (e.foreign_order || e.bytes != dtypeBytes(t)) return false;
  return t == DType::kFloat32 ? e.kind == 'f' : e.kind == 'u';
}

// A struct-module format as the buffer protocol gives it ("f", "<H", "=d", ...).
Element parseFormat(const char* format, std::size_t itemsize) {
  Element e;
  e.bytes = itemsize;
  std::string f = format ? format : "B";
  std::size_t at = 0;
  if (at < f.size() && std::string("@=<>!").find(f[at]) != std::string::npos) {
    e.foreign_order = f[at] == '>' || f[at] == '!';
    ++at;
  }
  if (f.size() - at != 1) {
    e.kind = 0;
    e.other = "format '" + f + "'";
    return e;
  }
  const char c = f[at];
  if (c == 'f' || c == 'd' || c == 'e')
    e.kind = 'f';
  else if (c == '?')
    e.kind = 'b';
  else if (std::string("bhilq").find(c) != std::string::npos)
    e.kind = 'i';
  else if (std::string("BHILQ").find(c) != std::string::npos)
    e.kind = 'u';
  else if (c == 'Z')
    e.kind = 'c';
  else {
    e.kind = 0;
    e.other = "format '" + f + "'";
  }
  if (e.bytes == 1) e.foreign_order = false;
  return e;
}

Element dlpackElement(const DLDataType& t) {
  Element e;
  e.bytes = t.bits / 8u;
  switch (t.code) {
    case kDLFloat:
      e.kind = 'f';
      break;
    case kDLInt:
      e.kind = 'i';
      break;
    case kDLUInt:
      e.kind = 'u';
      break;
    case kDLComplex:
      e.kind = 'c';
      break;
    default:
      e.kind = 0;
      e.other = "DLPack type code " + std::to_string(t.code) + " with " + std::to_string(t.bits) +
                " bits";
  }
  if (t.lanes != 1) {
    e.kind = 0;
    e.other = elementName(e) + " x" + std::to_string(t.lanes) + " lanes";
  }
  return e;
}

std::string shapeText(const std::vector<std::size_t>& shape) {
  std::ostringstream s;
  s << '(';
  for (std::size_t i = 0; i < shape.size(); ++i) s << (i ? ", " : "") << shape[i];
  s << (shape.size() == 1 ? ",)" : ")");
  return s.str();
}

std::string expectedShapeText(const std::vector<std::ptrdiff_t>& shape) {
  std::ostringstream s;
  s << '(';
  for (std::size_t i = 0; i < shape.size(); ++i) {
    s << (i ? ", " : "");
    if (shape[i] >= 0)
      s << shape[i];
    else
      s << (shape.size() == 2 && shape[0] < 0 && shape[1] < 0 ? (i == 0 ? "H" : "W") : "N");
  }
  s << (shape.size() == 1 ? ",)" : ")");
  return s.str();
}

std::string dtypeNames(const std::vector<DType>& dtypes) {
  std::string names;
  for (std::size_t i = 0; i < dtypes.size(); ++i)
    names += std::string(i ? " or " : "") + dtypeName(dtypes[i]);
  return names;
}

// What an argument must be, in words.
std::string expectedText(const std::vector<DType>& dtypes, const std::vector<std::ptrdiff_t>& shape,
                         std::optional<Layout> layout) {
  const std::string start = "a C-contiguous " + dtypeNames(dtypes) + " array of shape ";
  if (layout == Layout::kPoints) return start + "(N, 3), (H, W, 3) or (N, 4) with x, y, z first";
  if (layout == Layout::kDepth) return start + "(H, W) or (1, H, W)";
  return start + expectedShapeText(shape);
}

// What the caller passed, in words (its type, and its shape where it has one).
std::string describeObject(py::handle obj) {
  std::string text = py::str(py::type::handle_of(obj).attr("__qualname__"));
  if (py::hasattr(obj, "shape")) {
    try {
      text += " of shape " + std::string(py::str(py::tuple(obj.attr("shape"))));
    } catch (const py::error_already_set&) {
    }
  }
  return text;
}

// The conversion to `t` in the caller's library.
std::string conversion(DType t, bool torch) {
  if (!torch) return std::string(".astype(np.") + dtypeName(t) + ")";
  switch (t) {
    case DType::kFloat32:
      return "tensor.float()";
    case DType::kUint8:
      return "tensor.byte()";
    default:  // torch 1.13 has no uint16: through numpy
      return "tensor.numpy().astype(np.uint16)";
  }
}

// The element type of `element` among `dtypes`; TypeError naming `arg` and the conversion in
// the caller's library otherwise.
DType checkElement(py::handle obj, const char* arg, const Element& element,
                   const std::vector<DType>& dtypes, const std::string& expected,
                   const std::vector<std::size_t>& shape) {
  for (DType t : dtypes)
    if (matches(element, t)) return t;
  throw py::type_error(
      std::string(arg) + ": expected " + expected + ", got a " + elementName(element) +
      " array of shape " + shapeText(shape) + " (convert it explicitly, e.g. with " +
      conversion(dtypes.front(), isTorch(obj)) + ": octovk never copies an input silently)");
}

// Checks the shape against `expected_shape` (-1: any extent) and C order; throws ValueError
// naming `arg`, with the fix in torch's words where `obj` is a torch tensor (`strided_fix`, when
// not empty, instead of the usual one). Where `copy` allows it, strides or an alignment that
// cannot be read in place set *copied instead of throwing.
void checkLayout(py::handle obj, const char* arg, DType found, const std::string& expected,
                 const std::vector<std::size_t>& shape, const std::vector<std::ptrdiff_t>& strides,
                 const std::vector<std::ptrdiff_t>& expected_shape, const void* data, Copy copy,
                 const std::string& strided_fix, bool* copied) {
  bool shape_ok = shape.size() == expected_shape.size();
  for (std::size_t i = 0; shape_ok && i < shape.size(); ++i)
    if (expected_shape[i] >= 0 && shape[i] != static_cast<std::size_t>(expected_shape[i]))
      shape_ok = false;
  if (!shape_ok)
    throw py::value_error(std::string(arg) + ": expected " + expected + ", got shape " +
                          shapeText(shape));
  std::size_t count = 1;
  for (std::size_t extent : shape) count *= extent;
  if (count == 0) return;
  const auto item = static_cast<std::ptrdiff_t>(dtypeBytes(found));
  std::ptrdiff_t want = item;
  for (std::size_t d = shape.size(); d-- > 0;) {
    if (shape[d] != 1 && strides[d] != want) {
      if (copy == Copy::kAllowed) {
        *copied = true;
        return;
      }
      std::ostringstream s;
      if (!strided_fix.empty()) {
        s << arg << ": " << strided_fix << (copy == Copy::kRefused ? "; or pass copy=True" : "");
        throw py::value_error(s.str());
      }
      s << arg << ": expected " << expected << ", got strides (";
      for (std::size_t k = 0; k < strides.size(); ++k) s << (k ? ", " : "") << strides[k];
      s << (strides.size() == 1 ? ",)" : ")") << " bytes for shape " << shapeText(shape)
        << ", which is not C-contiguous (pass "
        << (isTorch(obj) ? std::string("tensor.contiguous()")
                         : "np.ascontiguousarray(" + std::string(arg) + ")")
        << (copy == Copy::kRefused ? ", or copy=True)" : ")");
      throw py::value_error(s.str());
    }
    want *= static_cast<std::ptrdiff_t>(shape[d]);
  }
  if (reinterpret_cast<std::uintptr_t>(data) % static_cast<std::uintptr_t>(item) != 0) {
    if (copy != Copy::kAllowed)
      throw py::value_error(std::string(arg) + ": the array's data is not aligned to its " +
                            std::to_string(item) + "-byte elements (copy it into a new array" +
                            (copy == Copy::kRefused ? ", or pass copy=True)" : ")"));
    *copied = true;
  }
}

// Copies the elements of a strided array into `out`, in C order.
void gather(const char* data, const std::vector<std::size_t>& shape,
            const std::vector<std::ptrdiff_t>& strides, std::size_t dim, std::size_t item,
            std::byte*& out) {
  for (std::size_t i = 0; i < shape[dim]; ++i) {
    const char* at = data + static_cast<std::ptrdiff_t>(i) * strides[dim];
    if (dim + 1 == shape.size()) {
      std::memcpy(out, at, item);
      out += item;
    } else {
      gather(at, shape, strides, dim + 1, item, out);
    }
  }
}

const char* deviceName(int type) {
  switch (type) {
    case kDLCUDA:
      return "cuda";
    case kDLCUDAHost:
      return "cuda_host";
    case kDLROCM:
      return "rocm";
    case kDLVulkan:
      return "vulkan";
    case kDLMetal:
      return "metal";
    case kDLOpenCL:
      return "opencl";
    default:
      return "device";
  }
}

}  // namespace

bool isTorch(py::handle obj) {
  const std::string module = py::str(py::type::handle_of(obj).attr("__module__"));
  return module == "torch" || module.rfind("torch.", 0) == 0;
}

py::object likeInput(py::handle input, py::object result) {
  if (!isTorch(input)) return result;
  return py::module_::import("torch").attr("from_dlpack")(result);
}

void warnDeprecated(const std::string& what) {
  if (PyErr_WarnEx(PyExc_DeprecationWarning, what.c_str(), 1) != 0) throw py::error_already_set();
}

std::uintptr_t lastInputAddress() noexcept { return g_last_input.load(); }
void noteInput(const void* data) noexcept {
  g_last_input.store(reinterpret_cast<std::uintptr_t>(data));
}

ArrayView::ArrayView(py::handle obj, const char* arg, std::initializer_list<DType> dtypes,
                     std::initializer_list<std::ptrdiff_t> shape, bool writable, Copy copy) {
  open(obj, arg, Want{dtypes, shape, std::nullopt}, writable, copy);
}

ArrayView::ArrayView(py::handle obj, const char* arg, Layout layout,
                     std::initializer_list<DType> dtypes, Copy copy) {
  open(obj, arg, Want{dtypes, {}, layout}, /*writable=*/false, copy);
}

void ArrayView::open(py::handle obj, const char* arg, const Want& want, bool writable, Copy copy) {
  if (PyObject_CheckBuffer(obj.ptr())) {
    fromBuffer(obj, arg, want, writable, copy);
  } else if (py::hasattr(obj, "__dlpack__")) {
    fromDlpack(obj, arg, want, copy);
  } else {
    throw py::type_error(std::string(arg) + ": expected " +
                         expectedText(want.dtypes, want.shape, want.layout) +
                         " (a numpy array or torch CPU tensor: the buffer protocol or "
                         "__dlpack__), got " +
                         describeObject(obj));
  }
}

ArrayView::~ArrayView() {
  if (has_buffer_) PyBuffer_Release(&buffer_);
}

void* ArrayView::copyOf(const void* data, const std::vector<std::ptrdiff_t>& strides) {
  const std::size_t item = dtypeBytes(dtype_);
  copied_.resize(size() * item);
  std::byte* out = copied_.data();
  gather(static_cast<const char*>(data), shape_, strides, 0, item, out);
  return copied_.data();
}

std::size_t ArrayView::size() const noexcept {
  std::size_t n = 1;
  for (std::size_t e : shape_) n *= e;
  return n;
}

void ArrayView::accept(py::handle obj, const char* arg, const Want& want, const Element& element,
                       std::vector<std::ptrdiff_t> strides, void* data, Copy copy) {
  const std::string expected = expectedText(want.dtypes, want.shape, want.layout);
  dtype_ = checkElement(obj, arg, element, want.dtypes, expected, shape_);
  std::vector<std::ptrdiff_t> expected_shape = want.shape;
  std::string strided_fix;
  bool organised = false;  // (H, W, 3) points: H * W of them
  if (want.layout == Layout::kPoints) {
    expected_shape = {-1, 3};
    if (shape_.size() == 3 && shape_[2] == 3) {
      expected_shape = {-1, -1, 3};
      organised = true;
    } else if (shape_.size() == 2 && shape_[1] == 4) {
      // x, y, z first: the first three columns, 4 elements apart (read in place only for N <= 1).
      shape_[1] = 3;
      strided_fix =
          "(N, 4) points are read as x, y, z, their first three columns, "
          "which are not packed xyz (each row holds a fourth value): octovk reads "
          "points in place only as (N, 3) or (H, W, 3), so these need a copy; pass " +
          (isTorch(obj) ? std::string(arg) + "[:, :3].contiguous()"
                        : "np.ascontiguousarray(" + std::string(arg) + "[:, :3])");
    }
  } else if (want.layout == Layout::kDepth) {
    expected_shape = {-1, -1};
    if (shape_.size() == 3 && shape_[0] == 1) {  // one channel first, as torch's (C, H, W)
      shape_.erase(shape_.begin());
      strides.erase(strides.begin());
    }
  }
  bool copied = false;
  checkLayout(obj, arg, dtype_, expected, shape_, strides, expected_shape, data, copy, strided_fix,
              &copied);
  data_ = copied ? copyOf(data, strides) : data;
  leading_.assign(shape_.begin(), shape_.end());
  if (want.layout == Layout::kPoints) {
    leading_.pop_back();  // one result per point: (N,) or (H, W)
    if (organised) shape_ = {shape_[0] * shape_[1], 3};
  }
}

void ArrayView::fromBuffer(py::handle obj, const char* arg, const Want& want, bool writable,
                           Copy copy) {
  if (PyObject_GetBuffer(obj.ptr(), &buffer_, PyBUF_RECORDS_RO) != 0) throw py::error_already_set();
  has_buffer_ = true;
  const Element element = parseFormat(buffer_.format, static_cast<std::size_t>(buffer_.itemsize));
  std::vector<std::ptrdiff_t> strides;
  for (int d = 0; d < buffer_.ndim; ++d) {
    shape_.push_back(static_cast<std::size_t>(buffer_.shape[d]));
    strides.push_back(buffer_.strides[d]);
  }
  accept(obj, arg, want, element, std::move(strides), buffer_.buf, copy);
  if (writable && buffer_.readonly)
    throw py::value_error(std::string(arg) + ": the array is read-only; pass a writable array");
}

void ArrayView::fromDlpack(py::handle obj, const char* arg, const Want& want, Copy copy) {
  // Refused before export: a CUDA tensor would need its memory imported into Vulkan (not built).
  if (py::hasattr(obj, "__dlpack_device__")) {
    const py::tuple device = obj.attr("__dlpack_device__")();
    const int type = device[0].cast<int>();
    if (type != kDLCPU)
      throw py::value_error(std::string(arg) + ": the tensor is on " + deviceName(type) + ":" +
                            std::string(py::str(device[1])) + " (DLPack device type " +
                            std::to_string(type) +
                            "); octovk reads host memory only: pass tensor.cpu()");
  }
  // DLPack has no sign or conjugate flag: torch exports a lazily negated view's memory as it is,
  // un-negated, so such a tensor would be read as other numbers than it holds.
  struct LazyView {
    const char* bit;
    const char* what;
    const char* fix;
  };
  for (const LazyView& lazy : {LazyView{"is_neg", "negated", "resolve_neg"},
                               LazyView{"is_conj", "conjugated", "resolve_conj"}})
    if (py::hasattr(obj, lazy.bit) && py::bool_(obj.attr(lazy.bit)()))
      throw py::value_error(std::string(arg) + ": the tensor is a lazily " + lazy.what +
                            " view (tensor." + lazy.bit + "() is True), whose memory holds " +
                            "other numbers than it shows; pass tensor." + lazy.fix +
                            "() (octovk never copies an input silently)");
  capsule_ = obj.attr("__dlpack__")();
  auto* managed = static_cast<DLManagedTensor*>(PyCapsule_GetPointer(capsule_.ptr(), "dltensor"));
  if (!managed) throw py::error_already_set();
  const DLTensor& t = managed->dl_tensor;
  if (t.device.device_type != kDLCPU)
    throw py::value_error(std::string(arg) + ": the tensor is on " +
                          deviceName(t.device.device_type) +
                          "; octovk reads host memory only: pass tensor.cpu()");
  const Element element = dlpackElement(t.dtype);
  std::vector<std::ptrdiff_t> strides(static_cast<std::size_t>(t.ndim));
  for (int d = 0; d < t.ndim; ++d) shape_.push_back(static_cast<std::size_t>(t.shape[d]));
  // DLPack strides count elements; none means compact row-major.
  std::ptrdiff_t compact = static_cast<std::ptrdiff_t>(element.bytes);
  for (int d = t.ndim; d-- > 0;) {
    strides[static_cast<std::size_t>(d)] =
        t.strides
            ? static_cast<std::ptrdiff_t>(t.strides[d]) * static_cast<std::ptrdiff_t>(element.bytes)
            : compact;
    compact *= static_cast<std::ptrdiff_t>(t.shape[d]);
  }
  accept(obj, arg, want, element, std::move(strides), static_cast<char*>(t.data) + t.byte_offset,
         copy);
}

Eigen::Vector3f toVector3(py::handle obj, const char* arg) {
  Eigen::Vector3f v;
  try {
    if (!obj.is_none() && py::len(obj) == 3) {
      for (int i = 0; i < 3; ++i) v[i] = py::float_(obj[py::int_(i)]).cast<float>();
      return v;
    }
  } catch (const py::error_already_set&) {
  }
  throw py::value_error(std::string(arg) +
                        ": expected 3 numbers (a sequence, array or tensor), got " +
                        describeObject(obj));
}

Eigen::Quaternionf toQuaternion(py::handle obj, const char* arg) {
  float c[4];
  try {
    if (py::len(obj) != 4) throw py::value_error();
    for (int i = 0; i < 4; ++i) c[i] = py::float_(obj[py::int_(i)]).cast<float>();
  } catch (const std::exception&) {
    throw py::value_error(std::string(arg) +
                          ": expected a quaternion of 4 numbers x, y, z, w, got " +
                          describeObject(obj));
  }
  const Eigen::Quaternionf q(c[3], c[0], c[1], c[2]);
  const float norm = q.norm();
  if (!(std::abs(norm - 1.0f) < 1e-3f))
    throw py::value_error(std::string(arg) + ": the quaternion (x, y, z, w) has norm " +
                          std::to_string(norm) + "; a rotation needs a unit quaternion");
  return q;
}

Pose toPose(py::handle obj, const char* arg) {
  if (obj.is_none()) return Pose{};
  if (py::isinstance<Pose>(obj)) return obj.cast<Pose>();
  const std::string what = std::string(arg) +
                           ": expected None, an octovk.Pose, a 4x4 rigid transform or a "
                           "(translation, quaternion x y z w) pair, got ";
  std::size_t n = 0;
  try {
    n = py::len(obj);
  } catch (const py::error_already_set&) {
    throw py::value_error(what + describeObject(obj));
  }
  Pose pose;
  if (n == 2) {
    pose.translation = toVector3(obj[py::int_(0)], arg);
    pose.rotation = toQuaternion(obj[py::int_(1)], arg);
    return pose;
  }
  if (n != 4) throw py::value_error(what + describeObject(obj));
  Eigen::Matrix4d m;
  try {
    for (int r = 0; r < 4; ++r) {
      py::object row = obj[py::int_(r)];
      if (py::len(row) != 4) throw py::value_error();
      for (int c = 0; c < 4; ++c) m(r, c) = py::float_(row[py::int_(c)]).cast<double>();
    }
  } catch (const std::exception&) {
    throw py::value_error(what + describeObject(obj));
  }
  const Eigen::Matrix3d rotation = m.topLeftCorner<3, 3>();
  const double off = (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).norm();
  const bool last_row = m(3, 0) == 0 && m(3, 1) == 0 && m(3, 2) == 0 && m(3, 3) == 1;
  if (!(off < 1e-4) || !(rotation.determinant() > 0) || !last_row)
    throw py::value_error(std::string(arg) +
                          ": the 4x4 matrix is not a rigid transform (its top-left 3x3 must "
                          "be a rotation and its last row 0 0 0 1)");
  pose.translation = m.topRightCorner<3, 1>().cast<float>();
  pose.rotation = Eigen::Quaterniond(rotation).cast<float>();
  return pose;
}

}  // namespace octovk::python
