#include "server/bench/emulator/pseudo_terminal.h"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace fesbench::server::emulator {

api::Result<PseudoTerminal> OpenPseudoTerminal() {
  PseudoTerminal pty;
  pty.master_fd = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (pty.master_fd < 0 || ::grantpt(pty.master_fd) != 0 || ::unlockpt(pty.master_fd) != 0) {
    const int error = errno;
    if (pty.master_fd >= 0) ::close(pty.master_fd);
    return api::Status::Unavailable(std::string("emulator: cannot open a pty: ") +
                                    std::strerror(error));
  }
  char name[128];
  if (::ptsname_r(pty.master_fd, name, sizeof name) != 0) {
    ::close(pty.master_fd);
    return api::Status::Unavailable("emulator: ptsname failed");
  }
  pty.port_path = name;
  termios tio{};
  ::tcgetattr(pty.master_fd, &tio);
  ::cfmakeraw(&tio);
  ::tcsetattr(pty.master_fd, TCSANOW, &tio);
  return pty;
}

}  // namespace fesbench::server::emulator
