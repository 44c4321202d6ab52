// SPDX-License-Identifier: MIT
// Element types and devices of tensors.
#pragma once

#include <cstddef>
#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

namespace g2l {

/// Element type. F32 for compute, F64 for CPU gradient checks, I32 for indices.
enum class DType : uint8_t { F32 = 0, F64 = 1, I32 = 2 };
constexpr int kDTypeCount = 3;

/// Bytes per element.
size_t dtype_size(DType t);
/// "f32", "f64", "i32".
const char* dtype_name(DType t);

template <class T> constexpr DType dtype_of();
template <> constexpr DType dtype_of<float>() { return DType::F32; }
template <> constexpr DType dtype_of<double>() { return DType::F64; }
template <> constexpr DType dtype_of<int32_t>() { return DType::I32; }

/// Where a tensor's storage lives.
enum class DeviceType : uint8_t { CPU = 0, CUDA = 1 };

struct Device {
    DeviceType type = DeviceType::CPU;
    int index = 0;
    static Device cpu() { return {DeviceType::CPU, 0}; }
    static Device cuda(int i = 0) { return {DeviceType::CUDA, i}; }
    bool is_cpu() const { return type == DeviceType::CPU; }
    bool is_cuda() const { return type == DeviceType::CUDA; }
    std::string str() const;  ///< "cpu" or "cuda:0"
    bool operator==(const Device& o) const { return type == o.type && index == o.index; }
    bool operator!=(const Device& o) const { return !(*this == o); }
};

/// Parses "cpu", "cuda", "cuda:1"; throws naming the text otherwise.
Device parse_device(const std::string& text);

/// True when g2l was built with G2L_WITH_CUDA and a CUDA device is present.
bool cuda_available();

/// Tensor shape: sizes per dimension (int64, row-major).
using Shape = std::vector<int64_t>;
/// Product of the sizes (1 for a scalar shape {}).
int64_t shape_numel(const Shape& s);
/// "[2, 3, 5]".
std::string shape_str(const Shape& s);

std::ostream& operator<<(std::ostream& os, const Shape& s);
std::ostream& operator<<(std::ostream& os, DType t);
std::ostream& operator<<(std::ostream& os, const Device& d);

}  // namespace g2l
