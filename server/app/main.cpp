// vdeform-server: the VolumeDeform reconstruction core as an LCM service, or offline over a data
// set (--input).
#include <cstdio>

#include "node.h"
#include "ocl/ocl.h"
#include "offline.h"
#include "server_options.h"
#include "vd/common/log.h"


int main(int argc, char** argv) {
  vd::ServerOptions options;
  vd::FlagParser flags(
      "vdeform-server: real-time non-rigid reconstruction (VolumeDeform) on OpenCL.\n"
      "  vdeform-server [flags]                 run as an LCM service: frames in, meshes and status out\n"
      "  vdeform-server --input SOURCE [flags]  run offline over a data set or synthetic scene");
  options.Register(&flags);
  // Every parameter is checked once, here, before anything starts.
  if (auto exit_code = flags.ParseCommandLine(argc, argv, "vdeform-server", [&] { return options.Validate(); }))
    return *exit_code;
  if (options.quiet) vd::SetLogLevel(vd::LogLevel::kWarning);
  if (options.list_devices) {
    auto devices = vd::ocl::ListDevices();
    if (!devices.ok()) {
      std::fprintf(stderr, "vdeform-server: %s\n", devices.status().ToString().c_str());
      return 1;
    }
    std::printf("%s", vd::ocl::DescribeDevices(*devices).c_str());
    return 0;
  }
  return options.input.empty() ? vd::RunNode(options) : vd::RunOffline(options);
}
