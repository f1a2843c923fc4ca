#pragma once
// SIGINT and SIGTERM ask a program to stop cleanly: the handler only sets a flag that the main
// loop polls (the signal also interrupts LCM's wait, so it is seen within one poll).
#include <atomic>

namespace vd {

// The flag the handlers set; main loops read it, and may set it themselves (a window closed).
std::atomic<bool>& StopFlag();
// Installs the handlers for SIGINT and SIGTERM, and ignores SIGPIPE (a peer that closed its socket
// must not kill the process).
void InstallStopSignalHandlers();

}  // namespace vd
