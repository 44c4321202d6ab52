// SPDX-License-Identifier: MIT
#include "core/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "core/error.h"

namespace g2l {

AtomicFile::AtomicFile(std::string path)
    // The temporary sits next to the target so the final rename() stays on one filesystem (and is
    // therefore atomic); the pid suffix keeps two processes writing the same path apart.
    : path_(std::move(path)), tmp_(path_ + ".tmp." + std::to_string(::getpid())) {
    fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    G2L_CHECK(fd_ >= 0, "cannot write '", path_, "': cannot create '", tmp_, "': ",
              std::strerror(errno));
}

AtomicFile::~AtomicFile() {
    if (fd_ >= 0) ::close(fd_);
    // Not committed means an exception interrupted the write: drop the partial file so `path` keeps
    // its previous contents.
    if (!committed_) std::remove(tmp_.c_str());
}

void AtomicFile::write(const void* data, size_t n) {
    G2L_CHECK(fd_ >= 0 && !committed_, "AtomicFile '", path_, "': write after commit");
    const char* p = static_cast<const char*>(data);
    while (n > 0) {
        const ssize_t w = ::write(fd_, p, n);
        // A signal can interrupt write() before any byte is written; that is not an error.
        if (w < 0 && errno == EINTR) continue;
        G2L_CHECK(w > 0, "cannot write '", path_, "': writing '", tmp_, "' failed: ",
                  std::strerror(errno));
        p += w;
        n -= size_t(w);
    }
}

void AtomicFile::commit(bool durable) {
    G2L_CHECK(fd_ >= 0 && !committed_, "AtomicFile '", path_, "': committed twice");
    // Without fsync the rename can reach the disk before the data does, and a crash would leave an
    // empty or truncated file under the final name.
    G2L_CHECK(!durable || ::fsync(fd_) == 0, "cannot write '", path_, "': fsync '", tmp_,
              "' failed: ", std::strerror(errno));
    // fd_ is cleared before close() so that the destructor never closes it a second time (the
    // descriptor number may already be reused) even if close() fails and throws.
    const int fd = fd_;
    fd_ = -1;
    G2L_CHECK(::close(fd) == 0, "cannot write '", path_, "': closing '", tmp_, "' failed: ",
              std::strerror(errno));
    G2L_CHECK(std::rename(tmp_.c_str(), path_.c_str()) == 0, "cannot write '", path_,
              "': renaming '", tmp_, "' over it failed: ", std::strerror(errno));
    // Set only after the rename succeeded: on any earlier failure the destructor removes tmp_.
    committed_ = true;
}

void write_file_atomic(const std::string& path, const std::string& bytes, bool durable) {
    AtomicFile f(path);
    f.write(bytes.data(), bytes.size());
    f.commit(durable);
}

}  // namespace g2l
