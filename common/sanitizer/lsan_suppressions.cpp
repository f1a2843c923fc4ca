// Compiled into every target of a VD_SANITIZE build (CMakeLists.txt): LeakSanitizer reads these
// at start-up. Only third-party libraries are listed: PoCL and its LLVM keep compiled kernels and
// caches until process exit, and the OpenNI2 drivers never free their device lists. A leak in our
// own code still fails the run.
extern "C" const char* __lsan_default_suppressions() {
  return "leak:libpocl.so\n"
         "leak:libLLVM-15.so\n"
         "leak:libclang-cpp.so\n"
         "leak:libOpenNI2.so\n"
         "leak:OpenNI2/Drivers/\n";
}
