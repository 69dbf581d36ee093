#include "osm_graph_slam/common/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace osm_graph_slam {

bool writeFileAtomically(const std::string& path, const std::string& content, std::string* error) {
  // POSIX rather than a stream: the reason of a failure (disk full, file too large) is kept, and
  // fsync before the rename makes sure a crash cannot leave the new name with missing data.
  const std::string tmp = path + ".tmp";
  const auto fail = [&](const std::string& what, int fd) {
    const std::string why = std::strerror(errno);
    if (fd >= 0) ::close(fd);
    std::remove(tmp.c_str());
    if (error) *error = what + ": " + why;
    return false;
  };
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return fail("cannot write '" + tmp + "'", -1);
  for (size_t done = 0; done < content.size();) {
    const ssize_t n = ::write(fd, content.data() + done, content.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return fail("cannot write '" + tmp + "'", fd);
    done += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) return fail("cannot write '" + tmp + "'", fd);
  if (::close(fd) != 0) return fail("cannot write '" + tmp + "'", -1);
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    return fail("cannot rename '" + tmp + "' to '" + path + "'", -1);
  return true;
}

}  // namespace osm_graph_slam
