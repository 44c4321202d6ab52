// SPDX-License-Identifier: MIT
// Checkpoint files (.g2l): named tensors + a JSON metadata string, in one self-describing,
// checksummed, little-endian file. Byte layout: docs/checkpoint.md. The metadata stays a string
// here (core does not interpret it); train/ and infer/ parse it.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/tensor.h"

namespace g2l {

/// Format version written by save_checkpoint and accepted by load_checkpoint.
constexpr uint32_t kCheckpointVersion = 1;
/// Data blocks start at multiples of this many bytes from the file start.
constexpr uint64_t kCheckpointAlign = 64;
/// Tensors may have at most this many dimensions.
constexpr int kCheckpointMaxDims = 8;

/// Writes `tensors` (in the given order) and `meta_json` to `path` atomically: the bytes go to
/// "<path>.tmp.<pid>", which is fsync'ed and renamed over `path` (the temporary file is removed
/// on failure). CUDA tensors are copied to the CPU first. Tensors may be of any dtype
/// (f32/f64/i32) and shape, including 0-d and empty ones.
/// Throws g2l::Error naming the file when: a tensor is undefined, a name is empty or repeated,
/// a tensor has more than kCheckpointMaxDims dimensions, meta_json is not valid JSON, or the
/// file cannot be written / renamed (with the OS error).
void save_checkpoint(const std::string& path,
                     const std::vector<std::pair<std::string, Tensor>>& tensors,
                     const std::string& meta_json);

/// The contents of a checkpoint file.
struct Checkpoint {
    std::string meta_json;                  ///< the metadata exactly as saved
    std::map<std::string, Tensor> tensors;  ///< CPU tensors, no autograd history
};

/// Reads a file written by save_checkpoint; the tensors are bitwise identical to the saved ones.
/// Throws g2l::Error naming the file and the problem: missing / unreadable; not a g2l checkpoint
/// (bad magic); unsupported version; truncated (the file is shorter than its header says, or
/// ends inside the header); checksum mismatch (corrupt); trailing bytes; duplicate or empty
/// tensor names; bad dtype code; too many dimensions; a data block that is misaligned, overlaps
/// another or the header, or whose size does not match its dims; metadata that is not JSON.
Checkpoint load_checkpoint(const std::string& path);

}  // namespace g2l
