#pragma once

/// @file
/// The pseudo-terminal an emulator answers on (README, "Without hardware:
/// the emulator"): its master side, raw, and the path of its slave side for
/// a driver to open as its serial port.

#include <string>

#include "api/status.h"

namespace fesbench::server::emulator {

struct PseudoTerminal {
  int master_fd = -1;     ///< owned by whoever opened it.
  std::string port_path;  ///< the slave side, /dev/pts/N.
};

/// Opens a pseudo-terminal in raw mode. kUnavailable with the system's
/// reason ("emulator: cannot open a pty: …", "emulator: ptsname failed");
/// nothing stays open then.
api::Result<PseudoTerminal> OpenPseudoTerminal();

}  // namespace fesbench::server::emulator
