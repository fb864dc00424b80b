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
#include <span>
#include <string>
#include <vector>

#include "checked.hpp"
#include "octovk/params.hpp"

namespace octovk::python {

namespace py = pybind11;

/// Element types the module reads or writes.
enum class DType { kFloat32, kUint16, kUint8 };

/// Whether an input that cannot be read in place (strides, alignment) is copied: a call with a
/// `copy` argument offers it, and copies where the caller passed copy=True.
enum class Copy { kNotOffered, kRefused, kAllowed };
inline Copy copyArgument(bool copy) { return copy ? Copy::kAllowed : Copy::kRefused; }

/// A caller's array, held (and its memory pinned) while alive. Destroy it with the GIL held.
class ArrayView {
 public:
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
  DType dtype() const noexcept { return dtype_; }
  std::size_t extent(std::size_t dim) const { return shape_.at(dim); }
  std::size_t size() const noexcept;

  /// An (N, 3) float32 array as N points, in place.
  std::span<const Eigen::Vector3f> points() const {
    return {static_cast<const Eigen::Vector3f*>(data_), extent(0)};
  }

 private:
  void fromBuffer(py::handle obj, const char* arg, std::initializer_list<DType> dtypes,
                  std::initializer_list<std::ptrdiff_t> shape, bool writable, Copy copy);
  void fromDlpack(py::handle obj, const char* arg, std::initializer_list<DType> dtypes,
                  std::initializer_list<std::ptrdiff_t> shape, Copy copy);
  /// Copies the array at `data` with `strides` (bytes) into copied_, in C order.
  void* copyOf(const void* data, const std::vector<std::ptrdiff_t>& strides);

  void* data_ = nullptr;
  DType dtype_ = DType::kFloat32;
  std::vector<std::size_t> shape_;
  Py_buffer buffer_{};
  bool has_buffer_ = false;
  py::object capsule_;  // the DLPack capsule: its destructor returns the tensor to its producer
  std::vector<std::byte> copied_;  // the elements in C order, where `copy` asked for them
};

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
