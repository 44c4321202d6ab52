// SPDX-License-Identifier: MIT
// .g2l checkpoint writer and reader (layout: docs/checkpoint.md).
//
// The reader loads the whole file into memory and parses it with a bounds-checked cursor, so
// no header value (lengths, counts, offsets) is trusted before it is compared with the file
// size: a truncated or corrupt file throws, it never reads out of bounds or allocates wildly.
#include "core/checkpoint.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>

#include "core/atomic_file.h"

namespace g2l {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
              "the .g2l writer copies tensor bytes as-is: little-endian hosts only");

namespace {

constexpr char kMagic[4] = {'G', '2', 'L', 'W'};
constexpr char kEndMagic[8] = {'G', '2', 'L', 'W', 'E', 'N', 'D', '\0'};
// magic + version + meta length + tensor count, and checksum + end magic.
constexpr uint64_t kFixedHead = 4 + 4 + 8 + 4;
constexpr uint64_t kTail = 8 + 8;

/// FNV-1a 64-bit, streamable: h = fnv1a(data, n, h).
constexpr uint64_t kFnvBasis = 0xcbf29ce484222325ull;
uint64_t fnv1a(const void* data, size_t n, uint64_t h) {
    const auto* p = static_cast<const unsigned char*>(data);
    // 0x100000001b3 is the 64-bit FNV prime. The checksum guards against corruption (truncated
    // copies, flipped bits), not tampering, so a simple dependency-free hash is enough.
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

template <class T>
void put(std::string& buf, T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));  // little endian (static_assert above)
    buf.append(b, sizeof(T));
}

uint64_t align_up(uint64_t x) {
    return (x + kCheckpointAlign - 1) / kCheckpointAlign * kCheckpointAlign;
}

struct Entry {
    std::string name;
    Tensor t;  // CPU
    uint64_t offset = 0;
};

/// Serialises everything before the first data block; fills in each entry's offset.
std::string build_header(std::vector<Entry>& entries, const std::string& meta) {
    std::string h(kMagic, 4);
    put<uint32_t>(h, kCheckpointVersion);
    put<uint64_t>(h, meta.size());
    h += meta;
    put<uint32_t>(h, uint32_t(entries.size()));
    uint64_t size = h.size();
    // Each record: name length u32, name, dtype u8, ndim u8, dims i64[ndim], offset u64,
    // nbytes u64. Records carry absolute data offsets, so the header's total size must be known
    // before the first record can be written.
    for (const Entry& e : entries) size += 4 + e.name.size() + 1 + 1 + 8 * e.t.dim() + 8 + 8;
    uint64_t offset = align_up(size);
    for (Entry& e : entries) {
        put<uint32_t>(h, uint32_t(e.name.size()));
        h += e.name;
        put<uint8_t>(h, uint8_t(e.t.dtype()));
        put<uint8_t>(h, uint8_t(e.t.dim()));
        for (int64_t d : e.t.shape()) put<int64_t>(h, d);
        e.offset = offset;
        put<uint64_t>(h, offset);
        put<uint64_t>(h, e.t.nbytes());
        offset = align_up(offset + e.t.nbytes());
    }
    G2L_ASSERT(h.size() == size);
    return h;
}

std::vector<Entry> collect(const std::string& path,
                           const std::vector<std::pair<std::string, Tensor>>& tensors) {
    std::vector<Entry> entries;
    std::set<std::string> names;
    for (const auto& [name, t] : tensors) {
        G2L_CHECK(!name.empty(), "save_checkpoint '", path, "': empty tensor name");
        G2L_CHECK(names.insert(name).second, "save_checkpoint '", path,
                  "': duplicate tensor name '", name, "'");
        G2L_CHECK(t.defined(), "save_checkpoint '", path, "': tensor '", name, "' is undefined");
        G2L_CHECK(t.dim() <= kCheckpointMaxDims, "save_checkpoint '", path, "': tensor '", name,
                  "' has ", t.dim(), " dims (at most ", kCheckpointMaxDims, ")");
        // Bytes are written straight from host memory, so device tensors are copied to the CPU.
        entries.push_back({name, t.to(Device::cpu()), 0});
    }
    return entries;
}

}  // namespace

void save_checkpoint(const std::string& path,
                     const std::vector<std::pair<std::string, Tensor>>& tensors,
                     const std::string& meta_json) {
    // Validated before anything is opened, so bad metadata never leaves a file behind.
    G2L_CHECK(nlohmann::json::accept(meta_json), "save_checkpoint '", path,
              "': metadata is not valid JSON (use \"{}\" for none): '",
              meta_json.substr(0, 80), "'");
    std::vector<Entry> entries = collect(path, tensors);
    const std::string header = build_header(entries, meta_json);

    AtomicFile f(path);
    // The checksum covers every byte before the tail (header, padding, data), which is exactly the
    // range load_checkpoint hashes.
    uint64_t h = fnv1a(header.data(), header.size(), kFnvBasis);
    f.write(header.data(), header.size());
    uint64_t pos = header.size();
    // Padding is written as zeros (not left unspecified) so equal inputs give byte-identical files.
    const std::string zeros(kCheckpointAlign, '\0');
    for (const Entry& e : entries) {
        const size_t pad = size_t(e.offset - pos);  // < kCheckpointAlign
        h = fnv1a(zeros.data(), pad, h);
        f.write(zeros.data(), pad);
        h = fnv1a(e.t.data(), e.t.nbytes(), h);
        f.write(e.t.data(), e.t.nbytes());
        pos = e.offset + e.t.nbytes();
    }
    std::string tail;
    put<uint64_t>(tail, h);
    tail.append(kEndMagic, 8);
    f.write(tail.data(), tail.size());
    f.commit();
}

// ---------------------------------------------------------------------------------------------
namespace {

/// Bounds-checked little-endian reader over the file bytes.
struct Cursor {
    const std::string& path;
    const std::string& buf;
    uint64_t pos = 0;

    void need(uint64_t n, const char* what) const {
        // Written as a subtraction (pos <= size always holds) so a huge corrupt n cannot overflow.
        G2L_CHECK(n <= buf.size() - pos, "checkpoint '", path, "' is truncated: it ends at byte ",
                  buf.size(), " inside the header (reading ", what, " at byte ", pos, ")");
    }
    template <class T>
    T get(const char* what) {
        need(sizeof(T), what);
        T v;
        std::memcpy(&v, buf.data() + pos, sizeof(T));
        pos += sizeof(T);
        return v;
    }
    std::string str(uint64_t n, const char* what) {
        need(n, what);
        std::string s = buf.substr(size_t(pos), size_t(n));
        pos += n;
        return s;
    }
};

std::string read_file(const std::string& path) {
    std::error_code ec;
    G2L_CHECK(std::filesystem::exists(path, ec), "checkpoint '", path, "' is missing");
    G2L_CHECK(std::filesystem::is_regular_file(path, ec), "checkpoint '", path,
              "' is not a regular file");
    std::ifstream in(path, std::ios::binary);
    G2L_CHECK(in.good(), "checkpoint '", path, "' is unreadable: ", std::strerror(errno));
    std::string buf((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    G2L_CHECK(!in.bad(), "checkpoint '", path, "': read error");
    return buf;
}

void check_magic_version(const std::string& path, const std::string& buf) {
    // Compare only the bytes that exist: a short foreign file is reported as "not a checkpoint"
    // before the size check can call it truncated.
    const size_t k = std::min<size_t>(buf.size(), 4);
    G2L_CHECK(std::memcmp(buf.data(), kMagic, k) == 0, "'", path,
              "' is not a g2l checkpoint (bad magic: expected 'G2LW' at byte 0)");
    G2L_CHECK(buf.size() >= kFixedHead + kTail, "checkpoint '", path, "' is truncated: ",
              buf.size(), " bytes, shorter than the smallest checkpoint (", kFixedHead + kTail,
              ")");
    uint32_t version;
    std::memcpy(&version, buf.data() + 4, 4);
    G2L_CHECK(version == kCheckpointVersion, "checkpoint '", path, "' has unsupported version ",
              version, " (this build reads version ", kCheckpointVersion,
              "; re-export it with a matching g2l)");
}

struct Record {
    std::string name;
    DType dtype;
    Shape shape;
    uint64_t offset, nbytes;
};

Record read_record(Cursor& c, uint32_t index) {
    const std::string& path = c.path;
    Record r;
    const uint32_t len = c.get<uint32_t>("a tensor name length");
    r.name = c.str(len, "a tensor name");
    G2L_CHECK(!r.name.empty(), "checkpoint '", path, "': tensor #", index, " has an empty name");
    const uint8_t dt = c.get<uint8_t>("a dtype");
    G2L_CHECK(dt < kDTypeCount, "checkpoint '", path, "': tensor '", r.name,
              "' has bad dtype code ", int(dt), " (known: 0 f32, 1 f64, 2 i32)");
    r.dtype = DType(dt);
    const uint8_t ndim = c.get<uint8_t>("ndim");
    G2L_CHECK(ndim <= kCheckpointMaxDims, "checkpoint '", path, "': tensor '", r.name, "' has ",
              int(ndim), " dims (at most ", kCheckpointMaxDims, ")");
    // The element count must fit in the file: compare against the file size as we multiply so a
    // corrupt dim cannot overflow.
    const uint64_t limit = c.buf.size();
    uint64_t numel = 1;
    bool zero = false;
    for (int d = 0; d < ndim; ++d) {
        const int64_t s = c.get<int64_t>("a dim");
        G2L_CHECK(s >= 0, "checkpoint '", path, "': tensor '", r.name, "' has negative dim ", s);
        r.shape.push_back(s);
        // Once a dim is 0 the tensor is empty whatever follows; later dims skip the overflow check.
        if (s == 0) zero = true;
        else if (!zero) {
            G2L_CHECK(numel <= limit / uint64_t(s), "checkpoint '", path, "': tensor '", r.name,
                      "' dims ", shape_str(r.shape), "... do not fit in a ", limit,
                      "-byte file (corrupt)");
            numel *= uint64_t(s);
        }
    }
    if (zero) numel = 0;
    r.offset = c.get<uint64_t>("a data offset");
    r.nbytes = c.get<uint64_t>("a data size");
    G2L_CHECK(r.nbytes == numel * dtype_size(r.dtype), "checkpoint '", path, "': tensor '",
              r.name, "' ", dtype_name(r.dtype), shape_str(r.shape), " needs ",
              numel * dtype_size(r.dtype), " bytes, header says ", r.nbytes);
    G2L_CHECK(r.offset % kCheckpointAlign == 0, "checkpoint '", path, "': tensor '", r.name,
              "' data offset ", r.offset, " is not ", kCheckpointAlign, "-byte aligned");
    return r;
}

/// Checks the data blocks lie between the header and the checksum without overlapping and that
/// the file is exactly as long as the header implies.
void check_layout(const std::string& path, std::vector<Record> recs, uint64_t header_end,
                  uint64_t file_size) {
    // recs is a copy: sorting by offset lets one pass check overlaps without trusting the writer's
    // order, and leaves the caller's record order (the file's order) untouched.
    std::sort(recs.begin(), recs.end(),
              [](const Record& a, const Record& b) { return a.offset < b.offset; });
    uint64_t end = header_end;
    for (const Record& r : recs) {
        G2L_CHECK(r.offset >= end, "checkpoint '", path, "': tensor '", r.name,
                  "' data at byte ", r.offset, " overlaps the header or another tensor (ends at ",
                  end, ")");
        G2L_CHECK(r.nbytes <= file_size && r.offset <= file_size - r.nbytes,
                  "checkpoint '", path, "' is truncated: tensor '", r.name, "' data ends at byte ",
                  r.offset + r.nbytes, " but the file has ", file_size, " bytes");
        end = r.offset + r.nbytes;
    }
    const uint64_t expected = end + kTail;
    G2L_CHECK(file_size >= expected, "checkpoint '", path, "' is truncated: the header implies ",
              expected, " bytes, the file has ", file_size);
    G2L_CHECK(file_size == expected, "checkpoint '", path, "' is corrupt: ",
              file_size - expected, " trailing bytes after the declared end at byte ", expected);
}

}  // namespace

Checkpoint load_checkpoint(const std::string& path) {
    const std::string buf = read_file(path);
    check_magic_version(path, buf);
    const uint64_t size = buf.size();
    // Checksum first, when the end marker is in place: any flipped byte is reported as
    // corruption rather than as whatever field it happened to damage.
    // Safe to read the last 8 bytes: check_magic_version guaranteed size >= kFixedHead + kTail.
    const bool has_end = std::memcmp(buf.data() + size - 8, kEndMagic, 8) == 0;
    if (has_end) {
        uint64_t stored;
        std::memcpy(&stored, buf.data() + size - kTail, 8);
        const uint64_t actual = fnv1a(buf.data(), size_t(size - kTail), kFnvBasis);
        G2L_CHECK(stored == actual, "checkpoint '", path, "' is corrupt: checksum mismatch "
                  "(stored ", std::hex, stored, ", computed ", actual, ")");
    }

    // Start after magic (4) and version (4), which check_magic_version already read.
    Cursor c{path, buf, 8};
    Checkpoint ck;
    const uint64_t meta_len = c.get<uint64_t>("the metadata length");
    ck.meta_json = c.str(meta_len, "the metadata");
    const uint32_t count = c.get<uint32_t>("the tensor count");
    std::vector<Record> recs;
    std::set<std::string> names;
    for (uint32_t i = 0; i < count; ++i) {
        recs.push_back(read_record(c, i));
        G2L_CHECK(names.insert(recs.back().name).second, "checkpoint '", path,
                  "': duplicate tensor name '", recs.back().name, "'");
    }
    check_layout(path, recs, c.pos, size);
    // Checked after check_layout so a truncated file gets the more precise "truncated" message
    // naming the tensor that runs past the end.
    G2L_CHECK(has_end, "checkpoint '", path, "' is corrupt: end marker 'G2LWEND' missing");
    G2L_CHECK(nlohmann::json::accept(ck.meta_json), "checkpoint '", path,
              "': metadata is not valid JSON");
    for (const Record& r : recs) {
        // Copied out of `buf` into allocator-owned (aligned) storage; `buf` is freed on return.
        Tensor t = Tensor::empty(r.shape, r.dtype);
        if (r.nbytes > 0) std::memcpy(t.data(), buf.data() + r.offset, size_t(r.nbytes));
        ck.tensors.emplace(r.name, t);
    }
    return ck;
}

}  // namespace g2l
