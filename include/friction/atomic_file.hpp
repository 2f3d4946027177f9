// Writing a file so that readers see the old content or the complete new one, never a mix.
//
// The content goes to a temporary file in the same directory as the target (so that the final
// rename stays within one file system, where POSIX rename(2) replaces the target atomically), is
// flushed and fsync'ed, then renamed over the target, and the directory is fsync'ed so the rename
// itself survives a crash.  If anything fails (the writer throws, the stream goes bad, the disk is
// full, the rename is refused) the temporary file is removed and the target is left untouched.
// The new file takes the permissions of the file it replaces, or 0666 minus the umask.
#pragma once

#include <filesystem>
#include <functional>
#include <iosfwd>
#include <string>
#include <string_view>

#include "friction/error.hpp"

namespace friction {

/// Write `path` atomically with whatever `write` puts into the stream.  Exceptions thrown by
/// `write` propagate unchanged (after clean-up); I/O failures throw FileError.
void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(std::ostream&)>& write);

/// Write `path` atomically with `contents`.
void write_file_atomically(const std::filesystem::path& path, std::string_view contents);

}  // namespace friction
