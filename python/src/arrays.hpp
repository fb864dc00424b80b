// Arrays in and out of the module: caller memory read in place through the buffer protocol or
// DLPack (numpy arrays, torch CPU tensors), and result arrays that own their memory.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "checked.hpp"
#include "octovk/params.hpp"

namespace octovk::python {

namespace py = pybind11;

/// Element types the module reads or writes.
enum class DType { kFloat32, kUint16, kUint8 };

/// An element type as the buffer protocol or DLPack describes it (arrays.cpp).
struct Element;

/// Whether an input that cannot be read in place (strides, alignment) is copied: a call with a
/// `copy` argument offers it, and copies where the caller passed copy=True.
enum class Copy { kNotOffered, kRefused, kAllowed };
inline Copy copyArgument(bool copy) { return copy ? Copy::kAllowed : Copy::kRefused; }

/// The shapes perception code hands over, each read as one canonical shape.
enum class Layout {
  /// Points, read as float32 (N, 3): (N, 3); an organised cloud (H, W, 3), H * W points row by
  /// row; (N, 4) with x, y, z first (x, y, z, intensity), its first three columns.
  kPoints,
  /// A depth image, read as (H, W): (H, W), or (1, H, W) with its one channel first (torch).
  kDepth,
};

/// A caller's array, held (and its memory pinned) while alive. Destroy it with the GIL held.
class ArrayView {
 public:
  /// Views `obj` in `layout` (its canonical shape: points (N, 3), depth (H, W)), in place where
  /// the strides allow, else as `copy` says (ValueError naming the fix, or a copy). leading()
  /// gives the shape one result per point or pixel takes: (N,), or (H, W) for an organised cloud.
  ArrayView(py::handle obj, const char* arg, Layout layout, std::initializer_list<DType> dtypes,
            Copy copy = Copy::kNotOffered);
  /// Views `obj` as a C-contiguous array of `dtype` (one of `dtypes`) with `shape` (-1: any
  /// extent), through the buffer protocol or else `__dlpack__`. `arg` names the argument in
  /// errors: TypeError for a wrong dtype or an object that is no array, ValueError for a wrong
  /// shape, strides, alignment, device, a torch view with its negative or conjugate bit set (read
  /// through DLPack, it would give other numbers) or a read-only array where `writable`. With
  /// Copy::kAllowed (an input only), strides or an alignment that cannot be read in place are
  /// copied.
  ArrayView(py::handle obj, const char* arg, std::initializer_list<DType> dtypes,
            std::initializer_list<std::ptrdiff_t> shape, bool writable = false,
            Copy copy = Copy::kNotOffered);
  ~ArrayView();
  ArrayView(const ArrayView&) = delete;
  ArrayView& operator=(const ArrayView&) = delete;

  void* data() const noexcept { return data_; }
  /// Whether the elements were copied (copy=True and strides that cannot be read in place).
  bool copied() const noexcept { return !copied_.empty(); }
  /// The shape of one result per point (Layout::kPoints) or pixel; the array's shape otherwise.
  const std::vector<py::ssize_t>& leading() const noexcept { return leading_; }
  DType dtype() const noexcept { return dtype_; }
  std::size_t extent(std::size_t dim) const { return shape_.at(dim); }
  std::size_t size() const noexcept;

  /// An (N, 3) float32 array as N points, in place.
  std::span<const Eigen::Vector3f> points() const {
    return {static_cast<const Eigen::Vector3f*>(data_), extent(0)};
  }

 private:
  /// What the caller's array must be: one fixed shape, or a layout.
  struct Want {
    std::vector<DType> dtypes;
    std::vector<std::ptrdiff_t> shape;  ///< -1: any extent (a fixed shape only)
    std::optional<Layout> layout;
  };
  void open(py::handle obj, const char* arg, const Want& want, bool writable, Copy copy);
  void fromBuffer(py::handle obj, const char* arg, const Want& want, bool writable, Copy copy);
  void fromDlpack(py::handle obj, const char* arg, const Want& want, Copy copy);
  /// Checks the element type, shape and strides of the array at `data` (shape_ and `strides`,
  /// in bytes, as its producer gives them), reshapes a layout to its canonical shape, and points
  /// data_ at the elements, or at a copy of them where `copy` allows and the strides ask for it.
  void accept(py::handle obj, const char* arg, const Want& want, const Element& element,
              std::vector<std::ptrdiff_t> strides, void* data, Copy copy);
  /// Copies the array at `data` with `strides` (bytes) into copied_, in C order.
  void* copyOf(const void* data, const std::vector<std::ptrdiff_t>& strides);

  void* data_ = nullptr;
  DType dtype_ = DType::kFloat32;
  std::vector<std::size_t> shape_;
  std::vector<py::ssize_t> leading_;
  Py_buffer buffer_{};
  bool has_buffer_ = false;
  py::object capsule_;  // the DLPack capsule: its destructor returns the tensor to its producer
  std::vector<std::byte> copied_;  // the elements in C order, where `copy` asked for them
};

/// Whether `obj` is a torch tensor (or a subclass, such as torch.nn.Parameter): fixes are then
/// spelt in torch's words, and results are tensors.
bool isTorch(py::handle obj);

/// `result` (a numpy array) as the caller's library has it: a torch tensor sharing its memory
/// (torch.from_dlpack) where `input` is a torch tensor, else `result` itself.
py::object likeInput(py::handle input, py::object result);

/// Issues a DeprecationWarning with `what` at the caller's line (an error where warnings are
/// errors: raised).
void warnDeprecated(const std::string& what);

/// `value` where the deprecated keyword `old_name` was not given, else the old argument's value,
/// with a DeprecationWarning: "OLD is deprecated: name it NEW (WHY); the old name goes in the next
/// release".
template <class T>
T renamed(T value, py::handle old, const char* old_name, const char* new_name,
          const char* why = "C++'s name") {
  if (old.is_none()) return value;
  warnDeprecated(std::string(old_name) + " is deprecated: name it " + new_name + " (" + why +
                 "); the old name goes in the next release");
  return old.cast<T>();
}

/// The address of the memory last handed to the library as a scan's points, a depth image's
/// pixels or query points (for the tests' zero-copy check: `octovk._last_input_address()`).
std::uintptr_t lastInputAddress() noexcept;
void noteInput(const void* data) noexcept;

/// A new numpy array of `shape` whose memory is `values`, moved into a capsule the array owns.
template <class T>
py::array_t<T> ownedArray(std::vector<T>&& values, std::vector<py::ssize_t> shape) {
  auto* heap = new std::vector<T>(std::move(values));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(std::move(shape), heap->data(), owner);
}

/// Three numbers from any sequence, array or tensor (ValueError naming `arg` otherwise).
Eigen::Vector3f toVector3(py::handle obj, const char* arg);

/// A unit quaternion from 4 numbers x, y, z, w (ValueError otherwise; not normalised).
Eigen::Quaternionf toQuaternion(py::handle obj, const char* arg);

/// A pose: None (identity), an octovk.Pose, a 4x4 rigid transform (nested sequences, array or
/// tensor) or a (translation, quaternion x y z w) pair.
Pose toPose(py::handle obj, const char* arg);

}  // namespace octovk::python
