// Atomic file replacement: temporary file, fsync, rename (see atomic_file.hpp).
#include "friction/atomic_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

namespace friction {
namespace {

std::string errno_text(int err) {
  return std::strerror(err);
}

// Owns the temporary file until it is renamed: closes and removes it on every other way out.
class TemporaryFile {
 public:
  explicit TemporaryFile(const std::filesystem::path& target) {
    const std::filesystem::path dir =
        target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
    static std::atomic<unsigned> counter{0};
    std::random_device entropy;
    for (int attempt = 0; attempt < 100; ++attempt) {
      // (built with a stream: GCC 12 reports a false -Wrestrict on `"." + std::string`)
      std::ostringstream name;
      name << '.' << target.filename().string() << ".tmp-" << ::getpid() << '-' << counter++ << '-'
           << entropy() % 100000;
      path_ = dir / name.str();
      fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
      if (fd_ >= 0) break;
      if (errno != EEXIST)
        throw FileError(
            target, "cannot create a temporary file in " + dir.string() + ": " + errno_text(errno));
    }
    if (fd_ < 0) throw FileError(target, "cannot find a free temporary file name");
    // Replacing a file keeps its permissions (open() above applied the umask to 0666).
    struct stat st;
    if (::stat(target.c_str(), &st) == 0) (void)::fchmod(fd_, st.st_mode & 07777);
  }
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  ~TemporaryFile() {
    close();
    if (!path_.empty()) ::unlink(path_.c_str());
  }

  const std::filesystem::path& path() const noexcept { return path_; }
  int fd() const noexcept { return fd_; }
  int close() noexcept {
    int rc = 0;
    if (fd_ >= 0) rc = ::close(fd_);
    fd_ = -1;
    return rc;
  }
  void release() noexcept { path_.clear(); }  // renamed: nothing left to remove

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

void sync_directory(const std::filesystem::path& target) {
  const std::filesystem::path dir =
      target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;  // best effort: the rename has happened already
  (void)::fsync(fd);
  ::close(fd);
}

}  // namespace

void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(std::ostream&)>& write) {
  if (path.empty()) throw FileError(path, "empty file name");
  TemporaryFile tmp(path);
  {
    std::ofstream out(tmp.path(), std::ios::binary | std::ios::trunc);
    if (!out) throw FileError(path, "cannot open the temporary file " + tmp.path().string());
    write(out);
    out.flush();
    if (!out) throw FileError(path, "writing failed (disk full or stream error)");
    out.close();
    if (!out) throw FileError(path, "closing the written file failed");
  }
  if (::fsync(tmp.fd()) != 0) throw FileError(path, "fsync failed: " + errno_text(errno));
  if (tmp.close() != 0) throw FileError(path, "close failed: " + errno_text(errno));
  if (::rename(tmp.path().c_str(), path.c_str()) != 0)
    throw FileError(path, "cannot replace the file: " + errno_text(errno));
  tmp.release();
  sync_directory(path);
}

void write_file_atomically(const std::filesystem::path& path, std::string_view contents) {
  write_file_atomically(path, [contents](std::ostream& out) {
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
  });
}

}  // namespace friction
