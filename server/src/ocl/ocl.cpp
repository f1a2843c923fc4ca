#include "ocl/ocl.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>

#include "vd/common/log.h"

namespace vd::ocl {

// Generated at build time from server/kernels (see server/CMakeLists.txt).
struct EmbeddedFile {
  const char* path;
  const char* text;
};
extern const EmbeddedFile kEmbeddedKernelFiles[];
extern const int kNumEmbeddedKernelFiles;

const char* ErrorName(cl_int err) {
  switch (err) {
#define VD_CASE(x) \
  case x: return #x;
    VD_CASE(CL_SUCCESS)
    VD_CASE(CL_DEVICE_NOT_FOUND)
    VD_CASE(CL_DEVICE_NOT_AVAILABLE)
    VD_CASE(CL_COMPILER_NOT_AVAILABLE)
    VD_CASE(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    VD_CASE(CL_OUT_OF_RESOURCES)
    VD_CASE(CL_OUT_OF_HOST_MEMORY)
    VD_CASE(CL_PROFILING_INFO_NOT_AVAILABLE)
    VD_CASE(CL_MEM_COPY_OVERLAP)
    VD_CASE(CL_IMAGE_FORMAT_MISMATCH)
    VD_CASE(CL_IMAGE_FORMAT_NOT_SUPPORTED)
    VD_CASE(CL_BUILD_PROGRAM_FAILURE)
    VD_CASE(CL_MAP_FAILURE)
    VD_CASE(CL_MISALIGNED_SUB_BUFFER_OFFSET)
    VD_CASE(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
    VD_CASE(CL_COMPILE_PROGRAM_FAILURE)
    VD_CASE(CL_LINKER_NOT_AVAILABLE)
    VD_CASE(CL_LINK_PROGRAM_FAILURE)
    VD_CASE(CL_DEVICE_PARTITION_FAILED)
    VD_CASE(CL_KERNEL_ARG_INFO_NOT_AVAILABLE)
    VD_CASE(CL_INVALID_VALUE)
    VD_CASE(CL_INVALID_DEVICE_TYPE)
    VD_CASE(CL_INVALID_PLATFORM)
    VD_CASE(CL_INVALID_DEVICE)
    VD_CASE(CL_INVALID_CONTEXT)
    VD_CASE(CL_INVALID_QUEUE_PROPERTIES)
    VD_CASE(CL_INVALID_COMMAND_QUEUE)
    VD_CASE(CL_INVALID_HOST_PTR)
    VD_CASE(CL_INVALID_MEM_OBJECT)
    VD_CASE(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR)
    VD_CASE(CL_INVALID_IMAGE_SIZE)
    VD_CASE(CL_INVALID_SAMPLER)
    VD_CASE(CL_INVALID_BINARY)
    VD_CASE(CL_INVALID_BUILD_OPTIONS)
    VD_CASE(CL_INVALID_PROGRAM)
    VD_CASE(CL_INVALID_PROGRAM_EXECUTABLE)
    VD_CASE(CL_INVALID_KERNEL_NAME)
    VD_CASE(CL_INVALID_KERNEL_DEFINITION)
    VD_CASE(CL_INVALID_KERNEL)
    VD_CASE(CL_INVALID_ARG_INDEX)
    VD_CASE(CL_INVALID_ARG_VALUE)
    VD_CASE(CL_INVALID_ARG_SIZE)
    VD_CASE(CL_INVALID_KERNEL_ARGS)
    VD_CASE(CL_INVALID_WORK_DIMENSION)
    VD_CASE(CL_INVALID_WORK_GROUP_SIZE)
    VD_CASE(CL_INVALID_WORK_ITEM_SIZE)
    VD_CASE(CL_INVALID_GLOBAL_OFFSET)
    VD_CASE(CL_INVALID_EVENT_WAIT_LIST)
    VD_CASE(CL_INVALID_EVENT)
    VD_CASE(CL_INVALID_OPERATION)
    VD_CASE(CL_INVALID_GL_OBJECT)
    VD_CASE(CL_INVALID_BUFFER_SIZE)
    VD_CASE(CL_INVALID_MIP_LEVEL)
    VD_CASE(CL_INVALID_GLOBAL_WORK_SIZE)
    VD_CASE(CL_INVALID_PROPERTY)
#undef VD_CASE
    case -1001: return "CL_PLATFORM_NOT_FOUND_KHR (no OpenCL platform / ICD)";
    default: return "CL_UNKNOWN_ERROR";
  }
}

Status ClError(cl_int err, const char* call, const char* file, int line) {
  const char* base = std::strrchr(file, '/');
  std::ostringstream os;
  os << call << " failed with " << ErrorName(err) << " (" << err << ") at " << (base ? base + 1 : file) << ":" << line;
  return Status(err == CL_MEM_OBJECT_ALLOCATION_FAILURE || err == CL_OUT_OF_RESOURCES || err == CL_OUT_OF_HOST_MEMORY
                    ? StatusCode::kUnavailable
                    : StatusCode::kInternal,
                os.str());
}

namespace {

std::string PlatformString(cl_platform_id p, cl_platform_info what) {
  size_t n = 0;
  if (clGetPlatformInfo(p, what, 0, nullptr, &n) != CL_SUCCESS || n == 0) return "?";
  std::string s(n, '\0');
  clGetPlatformInfo(p, what, n, s.data(), nullptr);
  while (!s.empty() && s.back() == '\0') s.pop_back();
  return s;
}

std::string DeviceString(cl_device_id d, cl_device_info what) {
  size_t n = 0;
  if (clGetDeviceInfo(d, what, 0, nullptr, &n) != CL_SUCCESS || n == 0) return "?";
  std::string s(n, '\0');
  clGetDeviceInfo(d, what, n, s.data(), nullptr);
  while (!s.empty() && s.back() == '\0') s.pop_back();
  return s;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

StatusOr<std::string> ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound("cannot read kernel file '" + path + "'");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Inlines `#include "shared/x.h"` / `#include "x.h"` from `files` (path -> text), once each.
Status Inline(const std::string& path, const std::map<std::string, std::string>& files, std::set<std::string>* done,
              std::string* out) {
  auto it = files.find(path);
  if (it == files.end()) return NotFound("kernel source includes unknown file '" + path + "'");
  if (!done->insert(path).second) return Status::Ok();
  std::istringstream in(it->second);
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t");
    // Only quoted includes are inlined; <...> includes sit in the host-only branch of vd_compat.h.
    if (first != std::string::npos && line.compare(first, 8, "#include") == 0 && line.find('"') != std::string::npos) {
      const auto q0 = line.find('"'), q1 = line.rfind('"');
      if (q1 <= q0) return InvalidArgument(path + ":" + std::to_string(line_no) + ": malformed #include");
      std::string inc = line.substr(q0 + 1, q1 - q0 - 1);
      if (inc.rfind("shared/", 0) != 0) inc = "shared/" + inc;
      VD_RETURN_IF_ERROR(Inline(inc, files, done, out));
      *out += "\n";
      continue;
    }
    *out += line;
    *out += "\n";
  }
  return Status::Ok();
}

}  // namespace

StatusOr<std::vector<DeviceInfo>> ListDevices() {
  cl_uint np = 0;
  cl_int err = clGetPlatformIDs(0, nullptr, &np);
  std::vector<DeviceInfo> out;
  if (err == -1001 || np == 0) return out;
  if (err != CL_SUCCESS) return ClError(err, "clGetPlatformIDs", __FILE__, __LINE__);
  std::vector<cl_platform_id> platforms(np);
  VD_CL_CHECK(clGetPlatformIDs(np, platforms.data(), nullptr));
  for (cl_uint p = 0; p < np; ++p) {
    cl_uint nd = 0;
    if (clGetDeviceIDs(platforms[p], CL_DEVICE_TYPE_ALL, 0, nullptr, &nd) != CL_SUCCESS || nd == 0) continue;
    std::vector<cl_device_id> devs(nd);
    VD_CL_CHECK(clGetDeviceIDs(platforms[p], CL_DEVICE_TYPE_ALL, nd, devs.data(), nullptr));
    for (cl_uint d = 0; d < nd; ++d) {
      DeviceInfo info;
      info.platform_index = static_cast<int>(p);
      info.device_index = static_cast<int>(d);
      info.global_index = static_cast<int>(out.size());
      info.platform_name = PlatformString(platforms[p], CL_PLATFORM_NAME);
      info.device_name = DeviceString(devs[d], CL_DEVICE_NAME);
      cl_device_type type = 0;
      clGetDeviceInfo(devs[d], CL_DEVICE_TYPE, sizeof(type), &type, nullptr);
      info.is_gpu = (type & CL_DEVICE_TYPE_GPU) != 0;
      info.is_cpu = (type & CL_DEVICE_TYPE_CPU) != 0;
      info.id = devs[d];
      info.platform = platforms[p];
      out.push_back(info);
    }
  }
  return out;
}

std::string DescribeDevices(const std::vector<DeviceInfo>& devices) {
  if (devices.empty()) {
    return "  (no OpenCL devices: install an ICD such as pocl-opencl-icd; PoCL also needs a writable "
           "POCL_CACHE_DIR or ~/.cache, else it lists zero devices)";
  }
  std::ostringstream os;
  for (const auto& d : devices) {
    os << "  [" << d.global_index << "] " << d.device_name << " (" << (d.is_gpu ? "GPU" : d.is_cpu ? "CPU" : "other")
       << ", platform '" << d.platform_name << "')\n";
  }
  return os.str();
}

StatusOr<std::string> AssembleProgramSource() {
  std::map<std::string, std::string> files;
  std::vector<std::string> kernels;
  for (int i = 0; i < kNumEmbeddedKernelFiles; ++i) {
    const std::string path = kEmbeddedKernelFiles[i].path;
    files[path] = kEmbeddedKernelFiles[i].text;
    if (path.find('/') == std::string::npos) kernels.push_back(path);
  }
  if (const char* dir = std::getenv("VD_KERNEL_DIR"); dir && *dir) {
    // Development: the same file names, read from disk so kernels change without a rebuild.
    VD_LOG_INFO << "reading kernels from VD_KERNEL_DIR=" << dir;
    for (auto& [path, text] : files) {
      VD_ASSIGN_OR_RETURN(text, ReadFile(std::string(dir) + "/" + path));
    }
  }
  std::string source;
  std::set<std::string> done;
  for (const auto& k : kernels) VD_RETURN_IF_ERROR(Inline(k, files, &done, &source));
  return source;
}

// Lanes of the laned kernels (Context::lanes()): explicit SIMD pays on a CPU device, where PoCL
// does not vectorise across work items; a GPU runs its work items in lockstep already.
StatusOr<int> ChooseLanes(const DeviceInfo& device) {
  if (const char* env = std::getenv("VD_LANES"); env && *env) {
    const std::string v = env;
    if (v == "1" || v == "4" || v == "8" || v == "16") return std::stoi(v);
    return InvalidArgument("VD_LANES='" + v + "': expected 1, 4, 8 or 16");
  }
  if (!device.is_cpu) return 1;
  cl_uint width = 1;
  if (clGetDeviceInfo(device.id, CL_DEVICE_PREFERRED_VECTOR_WIDTH_FLOAT, sizeof(width), &width, nullptr) != CL_SUCCESS)
    return 1;
  return width >= 16 ? 16 : width >= 8 ? 8 : width >= 4 ? 4 : 1;
}

StatusOr<std::unique_ptr<Context>> Context::Create(const std::string& spec) {
  VD_ASSIGN_OR_RETURN(auto devices, ListDevices());
  if (devices.empty()) return Unavailable("no OpenCL device found.\n" + DescribeDevices(devices));
  const DeviceInfo* chosen = nullptr;
  if (spec.empty()) {
    for (const auto& d : devices)
      if (d.is_gpu && !chosen) chosen = &d;
    for (const auto& d : devices)
      if (d.is_cpu && !chosen) chosen = &d;
    if (!chosen) chosen = &devices.front();
  } else if (std::all_of(spec.begin(), spec.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); })) {
    const long idx = std::strtol(spec.c_str(), nullptr, 10);
    if (idx >= 0 && idx < static_cast<long>(devices.size())) chosen = &devices[idx];
  } else {
    for (const auto& d : devices) {
      if (!chosen && (Lower(d.device_name).find(Lower(spec)) != std::string::npos ||
                      Lower(d.platform_name).find(Lower(spec)) != std::string::npos))
        chosen = &d;
    }
  }
  if (!chosen) return NotFound("no OpenCL device matches --device '" + spec + "'; available:\n" + DescribeDevices(devices));
  // The rasteriser keeps depth and triangle id per pixel with one 64-bit atomic min (raster.cl).
  const std::string extensions = DeviceString(chosen->id, CL_DEVICE_EXTENSIONS);
  for (const char* needed : {"cl_khr_int64_base_atomics", "cl_khr_int64_extended_atomics"})
    if (extensions.find(needed) == std::string::npos)
      return Unavailable("OpenCL device '" + chosen->device_name + "' lacks " + needed +
                         " (64-bit atomics), which vdeform's rasteriser needs; choose another with --device:\n" +
                         DescribeDevices(devices));

  std::unique_ptr<Context> ctx(new Context());
  ctx->device_ = *chosen;
  cl_int err = CL_SUCCESS;
  cl_context_properties props[] = {CL_CONTEXT_PLATFORM, reinterpret_cast<cl_context_properties>(chosen->platform), 0};
  ctx->context_ = clCreateContext(props, 1, &chosen->id, nullptr, nullptr, &err);
  if (err != CL_SUCCESS) return ClError(err, "clCreateContext", __FILE__, __LINE__);
  ctx->queue_ = clCreateCommandQueue(ctx->context_, chosen->id, 0, &err);
  if (err != CL_SUCCESS) return ClError(err, "clCreateCommandQueue", __FILE__, __LINE__);
  VD_ASSIGN_OR_RETURN(ctx->lanes_, ChooseLanes(*chosen));
  VD_RETURN_IF_ERROR(ctx->Build());
  return ctx;
}

StatusOr<std::unique_ptr<Context>> Context::CreateSibling() const {
  std::unique_ptr<Context> s(new Context());
  s->device_ = device_;
  s->lanes_ = lanes_;
  cl_int err = CL_SUCCESS;
  s->queue_ = clCreateCommandQueue(context_, device_.id, 0, &err);
  if (err != CL_SUCCESS) return ClError(err, "clCreateCommandQueue", __FILE__, __LINE__);
  VD_CL_CHECK(clRetainContext(context_));
  s->context_ = context_;
  VD_CL_CHECK(clRetainProgram(program_));
  s->program_ = program_;
  return s;
}

Context::~Context() {
  if (!profile_.empty()) {
    std::vector<std::pair<double, std::string>> rows;
    for (const auto& [name, e] : profile_) rows.emplace_back(e.first, name);
    std::sort(rows.rbegin(), rows.rend());
    std::fprintf(stderr, "kernel profile (ms total, launches):\n");
    for (const auto& [ms, name] : rows) std::fprintf(stderr, "  %-32s %10.1f %8lld\n", name.c_str(), ms, profile_[name].second);
  }
  for (auto& [name, k] : kernels_) clReleaseKernel(k.first);
  if (program_) clReleaseProgram(program_);
  if (queue_) clReleaseCommandQueue(queue_);
  if (context_) clReleaseContext(context_);
}

std::string Context::Describe() const {
  return device_.device_name + " (" + (device_.is_gpu ? "GPU" : device_.is_cpu ? "CPU" : "other") + ", " +
         device_.platform_name + ")";
}

// A program build slower than this compiled rather than came from a cache.
constexpr double kSlowBuildSeconds = 3.0;

Status Context::Build() {
  VD_ASSIGN_OR_RETURN(std::string source, AssembleProgramSource());
  const char* text = source.c_str();
  const size_t len = source.size();
  cl_int err = CL_SUCCESS;
  program_ = clCreateProgramWithSource(context_, 1, &text, &len, &err);
  if (err != CL_SUCCESS) return ClError(err, "clCreateProgramWithSource", __FILE__, __LINE__);
  // Argument info lets FindKernel check each handle's read/write/value kinds, not only its count
  // (PoCL reports none without it); it is metadata and leaves the generated code alone.
  std::string options = "-cl-std=CL1.2 -cl-kernel-arg-info -DVD_LANES=" + std::to_string(lanes_);
  cl_device_fp_config fp = 0;
  clGetDeviceInfo(device_.id, CL_DEVICE_SINGLE_FP_CONFIG, sizeof(fp), &fp, nullptr);
  // Same division and square root as the host reference where the device can.
  if (fp & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT) options += " -cl-fp32-correctly-rounded-divide-sqrt";
  const auto build_start = std::chrono::steady_clock::now();
  err = clBuildProgram(program_, 1, &device_.id, options.c_str(), nullptr, nullptr);
  const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - build_start).count();
  // A cached build takes well under a second; one that compiled means the kernels will compile
  // too, each at its first launch, and a live stream loses its first seconds meanwhile.
  if (err == CL_SUCCESS && build_s > kSlowBuildSeconds)
    VD_LOG_INFO << "OpenCL program compiled in " << std::fixed << std::setprecision(1) << build_s
                << " s: the kernel cache (POCL_CACHE_DIR, else ~/.cache/pocl/kcache for PoCL) was cold; the "
                   "first frames also compile their kernels (seconds); later starts are fast "
                   "(deploy/setup.sh warms the cache)";
  if (err != CL_SUCCESS) {
    size_t n = 0;
    clGetProgramBuildInfo(program_, device_.id, CL_PROGRAM_BUILD_LOG, 0, nullptr, &n);
    std::string log(n, '\0');
    clGetProgramBuildInfo(program_, device_.id, CL_PROGRAM_BUILD_LOG, n, log.data(), nullptr);
    return Internal(std::string("OpenCL program build failed (") + ErrorName(err) + ") on " + Describe() +
                    ". Build log:\n" + log);
  }
  return Status::Ok();
}

namespace {

// The program's view of kernel k as FindKernel's letters.
StatusOr<std::string> ProgramSignature(cl_kernel k, const char* name) {
  cl_uint n = 0;
  cl_int err = clGetKernelInfo(k, CL_KERNEL_NUM_ARGS, sizeof(n), &n, nullptr);
  if (err != CL_SUCCESS) return ClError(err, (std::string("clGetKernelInfo ") + name).c_str(), __FILE__, __LINE__);
  std::string sig(n, '?');
  for (cl_uint i = 0; i < n; ++i) {
    cl_kernel_arg_address_qualifier address = 0;
    cl_kernel_arg_type_qualifier type = 0;
    if (clGetKernelArgInfo(k, i, CL_KERNEL_ARG_ADDRESS_QUALIFIER, sizeof(address), &address, nullptr) != CL_SUCCESS ||
        clGetKernelArgInfo(k, i, CL_KERNEL_ARG_TYPE_QUALIFIER, sizeof(type), &type, nullptr) != CL_SUCCESS)
      continue;
    if (address == CL_KERNEL_ARG_ADDRESS_PRIVATE) sig[i] = 's';
    if (address == CL_KERNEL_ARG_ADDRESS_GLOBAL) sig[i] = (type & CL_KERNEL_ARG_TYPE_CONST) ? 'r' : 'w';
  }
  return sig;
}

bool SignaturesAgree(const std::string& program, const char* handle) {
  if (program.size() != std::strlen(handle)) return false;
  for (size_t i = 0; i < program.size(); ++i)
    if (program[i] != '?' && program[i] != handle[i]) return false;
  return true;
}

}  // namespace

StatusOr<cl_kernel> Context::FindKernel(const char* name, const char* signature) {
  std::lock_guard<std::mutex> lock(kernels_mutex_);
  auto it = kernels_.find(name);
  if (it == kernels_.end()) {
    cl_int err = CL_SUCCESS;
    cl_kernel k = clCreateKernel(program_, name, &err);
    if (err != CL_SUCCESS) return ClError(err, (std::string("clCreateKernel ") + name).c_str(), __FILE__, __LINE__);
    StatusOr<std::string> sig = ProgramSignature(k, name);
    if (!sig.ok()) {
      clReleaseKernel(k);
      return sig.status();
    }
    it = kernels_.emplace(name, std::make_pair(k, std::move(sig).value())).first;
  }
  // Checked on every launch: two handles may name one kernel (a test declares a wrong one).
  if (!SignaturesAgree(it->second.second, signature)) {
    return Internal(std::string(name) + " has arguments '" + it->second.second + "' in the program but its handle '" +
                    signature + "' (w: __global T*, r: __global const T*, s: value; vd_items last)");
  }
  return it->second.first;
}

Status Context::Enqueue(cl_kernel k, const char* name, size_t work_items, size_t local) {
  const size_t global = (work_items + local - 1) / local * local;
  // Development profile ($VD_PROFILE_KERNELS set): every launch waits for the device and its wall
  // time is summed per kernel; the totals are printed when the context goes away.
  const bool profile = profile_enabled_;
  const auto t0 = std::chrono::steady_clock::now();
  if (profile) clFinish(queue_);
  cl_int err = clEnqueueNDRangeKernel(queue_, k, 1, nullptr, &global, &local, 0, nullptr, nullptr);
  if (err != CL_SUCCESS) return ClError(err, (std::string("clEnqueueNDRangeKernel ") + name).c_str(), __FILE__, __LINE__);
  if (profile) {
    clFinish(queue_);
    auto& e = profile_[name];
    e.first += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    e.second += 1;
  }
  return Status::Ok();
}

Status Context::Wait(PendingRead* pending) {
  const cl_int err = pending->Release();
  if (err != CL_SUCCESS) return ClError(err, "clWaitForEvents", __FILE__, __LINE__);
  return Status::Ok();
}

Status Context::Finish() {
  VD_CL_CHECK(clFinish(queue_));
  return Status::Ok();
}

}  // namespace vd::ocl
