// SPDX-License-Identifier: MIT
// Files written whole or not at all. Every file we write that a kill or a full disk must not
// leave half-written (checkpoints, model exports, a run's config.json and rewritten logs, the
// BOP files g2l_render writes) goes through here.
#pragma once

#include <cstddef>
#include <string>

namespace g2l {

/// Bytes go to "<path>.tmp.<pid>"; commit() fsyncs, closes and renames it over `path`. An
/// AtomicFile destroyed without commit() (an exception on the way) removes its temporary file
/// and leaves `path` as it was. Every failure throws g2l::Error naming the file and the OS's
/// reason.
class AtomicFile {
public:
    explicit AtomicFile(std::string path);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    /// Appends n bytes (retries short writes and EINTR).
    void write(const void* data, size_t n);
    /// fsync (unless `durable` is false: files that can be made again, such as rendered
    /// images, skip it), close, rename over path(). Once only.
    void commit(bool durable = true);

    const std::string& path() const { return path_; }
    const std::string& temp_path() const { return tmp_; }

private:
    std::string path_, tmp_;
    int fd_ = -1;
    bool committed_ = false;
};

/// `bytes` to `path` through an AtomicFile (commit(durable)).
void write_file_atomic(const std::string& path, const std::string& bytes, bool durable = true);

}  // namespace g2l
