// SPDX-License-Identifier: MIT
#include "core/dtype.h"

#include "core/device_cuda.h"
#include "core/error.h"

namespace g2l {

size_t dtype_size(DType t) {
    switch (t) {
        case DType::F32: return 4;
        case DType::F64: return 8;
        case DType::I32: return 4;
    }
    // Only reachable with an out-of-range enum value (a bad cast from an integer).
    G2L_CHECK(false, "dtype_size: unknown dtype ", int(t));
}

const char* dtype_name(DType t) {
    switch (t) {
        case DType::F32: return "f32";
        case DType::F64: return "f64";
        case DType::I32: return "i32";
    }
    // No throw here: dtype_name is used while building error messages.
    return "?";
}

std::string Device::str() const {
    return is_cpu() ? std::string("cpu") : cat("cuda:", index);
}

Device parse_device(const std::string& text) {
    if (text == "cpu") return Device::cpu();
    if (text == "cuda") return Device::cuda(0);
    if (text.rfind("cuda:", 0) == 0 && text.size() > 5) {
        try {
            size_t used = 0;
            const int i = std::stoi(text.substr(5), &used);
            // `used` must cover the whole suffix, so "cuda:1x" is rejected, not read as cuda:1.
            if (used == text.size() - 5 && i >= 0) return Device::cuda(i);
        // stoi throws on non-digits and overflow; fall through to the one error message below.
        } catch (const std::exception&) {
        }
    }
    G2L_CHECK(false, "unknown device '", text, "' (expected cpu, cuda or cuda:N)");
}

bool cuda_available() { return cuda::device_count() > 0; }

int64_t shape_numel(const Shape& s) {
    int64_t n = 1;
    for (int64_t d : s) n *= d;
    return n;
}

std::string shape_str(const Shape& s) {
    std::string out = "[";
    for (size_t i = 0; i < s.size(); ++i) out += (i ? ", " : "") + std::to_string(s[i]);
    return out + "]";
}

std::ostream& operator<<(std::ostream& os, const Shape& s) { return os << shape_str(s); }
std::ostream& operator<<(std::ostream& os, DType t) { return os << dtype_name(t); }
std::ostream& operator<<(std::ostream& os, const Device& d) { return os << d.str(); }

}  // namespace g2l
