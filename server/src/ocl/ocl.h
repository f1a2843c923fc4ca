#pragma once
// OpenCL runtime: device selection, the embedded program built once, RAII buffers and checked
// kernel launches (through the typed handles of ocl/kernel.h). Every OpenCL call is checked and
// reported with its error name and call site.
#ifndef CL_TARGET_OPENCL_VERSION
#define CL_TARGET_OPENCL_VERSION 120
#endif
#include <CL/cl.h>

#include <algorithm>
#include <climits>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "vd/common/status.h"

namespace vd::ocl {

const char* ErrorName(cl_int err);
Status ClError(cl_int err, const char* call, const char* file, int line);

#define VD_CL_CHECK(call)                                                        \
  do {                                                                           \
    cl_int vd_cl_err_ = (call);                                                  \
    if (vd_cl_err_ != CL_SUCCESS) return ::vd::ocl::ClError(vd_cl_err_, #call, __FILE__, __LINE__); \
  } while (0)

struct DeviceInfo {
  int platform_index = 0;
  int device_index = 0;
  // Index over all devices of all platforms, as --device takes it.
  int global_index = 0;
  std::string platform_name;
  std::string device_name;
  bool is_gpu = false;
  bool is_cpu = false;
  cl_device_id id = nullptr;
  cl_platform_id platform = nullptr;
};

// All devices of all platforms. An error only when the ICD loader itself fails.
StatusOr<std::vector<DeviceInfo>> ListDevices();
// One line per device, for error messages and --list-devices.
std::string DescribeDevices(const std::vector<DeviceInfo>& devices);

class Context;
template <class Signature>
class Kernel;

// A device buffer of n elements of T; movable, released on destruction.
template <typename T>
class Buffer {
 public:
  Buffer() = default;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  Buffer(Buffer&& o) noexcept : mem_(o.mem_), size_(o.size_), counter_(o.counter_) {
    o.mem_ = nullptr;
    o.size_ = 0;
  }
  Buffer& operator=(Buffer&& o) noexcept {
    if (this != &o) {
      Release();
      mem_ = o.mem_;
      size_ = o.size_;
      counter_ = o.counter_;
      o.mem_ = nullptr;
      o.size_ = 0;
    }
    return *this;
  }
  ~Buffer() { Release(); }

  cl_mem mem() const { return mem_; }
  size_t size() const { return size_; }
  size_t bytes() const { return size_ * sizeof(T); }
  bool empty() const { return size_ == 0; }

 private:
  friend class Context;
  void Release() {
    if (mem_) {
      clReleaseMemObject(mem_);
      if (counter_) *counter_ -= bytes();
    }
    mem_ = nullptr;
    size_ = 0;
  }
  cl_mem mem_ = nullptr;
  size_t size_ = 0;
  // The owning context's allocation counter (the context outlives its buffers).
  size_t* counter_ = nullptr;
};

// A download queued without waiting (Context::DownloadAsync); Context::Wait blocks until it is
// done. Move-only: it owns its OpenCL event, and destroying (or replacing) it waits for the
// download too, so the host memory it writes never outlives it unnoticed.
class PendingRead {
 public:
  PendingRead() = default;
  PendingRead(PendingRead&& o) noexcept : event_(o.event_) { o.event_ = nullptr; }
  PendingRead& operator=(PendingRead&& o) noexcept {
    Release();
    std::swap(event_, o.event_);
    return *this;
  }
  PendingRead(const PendingRead&) = delete;
  PendingRead& operator=(const PendingRead&) = delete;
  ~PendingRead() { Release(); }
  bool pending() const { return event_ != nullptr; }

 private:
  // Waits for the download (if any) and lets its event go; the wait's result.
  cl_int Release() {
    if (!event_) return CL_SUCCESS;
    const cl_int err = clWaitForEvents(1, &event_);
    clReleaseEvent(event_);
    event_ = nullptr;
    return err;
  }
  friend class Context;
  cl_event event_ = nullptr;
};

class Context {
 public:
  // device_spec: "" (first GPU, else first CPU device), an index into ListDevices(), or a
  // case-insensitive substring of the platform or device name.
  static StatusOr<std::unique_ptr<Context>> Create(const std::string& device_spec);
  // A second in-order queue on the same device, context and program (its own kernel objects), so
  // another host thread can run work beside this one's; buffers of either work in both. Its
  // allocations count in its own totals. This context must outlive it.
  StatusOr<std::unique_ptr<Context>> CreateSibling() const;
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  const DeviceInfo& device() const { return device_; }
  std::string Describe() const;

  template <typename T>
  StatusOr<Buffer<T>> Alloc(size_t n) {
    Buffer<T> b;
    if (n == 0) return b;
    cl_int err = CL_SUCCESS;
    b.mem_ = clCreateBuffer(context_, CL_MEM_READ_WRITE, n * sizeof(T), nullptr, &err);
    if (err != CL_SUCCESS) return ClError(err, "clCreateBuffer", __FILE__, __LINE__);
    b.size_ = n;
    b.counter_ = &allocated_bytes_;
    allocated_bytes_ += n * sizeof(T);
    peak_bytes_ = std::max(peak_bytes_, allocated_bytes_);
    return b;
  }
  // Grows the buffer to at least n elements (contents are not kept); no-op when big enough.
  template <typename T>
  Status Reserve(Buffer<T>* b, size_t n) {
    if (b->size() >= n) return Status::Ok();
    *b = Buffer<T>();
    VD_ASSIGN_OR_RETURN(*b, Alloc<T>(n + n / 4));
    return Status::Ok();
  }
  template <typename T>
  Status Upload(Buffer<T>& b, const T* data, size_t n, size_t offset = 0) {
    if (offset + n > b.size()) return OutOfRange("upload past the end of a device buffer");
    if (n == 0) return Status::Ok();
    VD_CL_CHECK(clEnqueueWriteBuffer(queue_, b.mem(), CL_TRUE, offset * sizeof(T), n * sizeof(T), data, 0, nullptr, nullptr));
    return Status::Ok();
  }
  template <typename T>
  Status Download(const Buffer<T>& b, T* data, size_t n, size_t offset = 0) {
    if (offset + n > b.size()) return OutOfRange("download past the end of a device buffer");
    if (n == 0) return Status::Ok();
    VD_CL_CHECK(clEnqueueReadBuffer(queue_, b.mem(), CL_TRUE, offset * sizeof(T), n * sizeof(T), data, 0, nullptr, nullptr));
    return Status::Ok();
  }
  // Queues a download and returns at once: the host can queue more work behind it and then Wait,
  // which returns when the commands before the download and the download are done, while the
  // device goes on with the rest (a host round trip without idling the device). `data` must stay
  // valid until Wait (or until `pending` is destroyed, which waits too).
  template <typename T>
  Status DownloadAsync(const Buffer<T>& b, T* data, size_t n, PendingRead* pending) {
    if (n > b.size()) return OutOfRange("download past the end of a device buffer");
    *pending = PendingRead();
    if (n == 0) return Status::Ok();
    cl_event event = nullptr;
    VD_CL_CHECK(clEnqueueReadBuffer(queue_, b.mem(), CL_FALSE, 0, n * sizeof(T), data, 0, nullptr, &event));
    pending->event_ = event;
    VD_CL_CHECK(clFlush(queue_));
    return Status::Ok();
  }
  // Blocks until `pending`'s download is done (no-op when none is pending).
  Status Wait(PendingRead* pending);
  template <typename T>
  Status Fill(Buffer<T>& b, const T& value, size_t n, size_t offset = 0) {
    if (offset + n > b.size()) return OutOfRange("fill past the end of a device buffer");
    if (n == 0) return Status::Ok();
    VD_CL_CHECK(clEnqueueFillBuffer(queue_, b.mem(), &value, sizeof(T), offset * sizeof(T), n * sizeof(T), 0, nullptr,
                                    nullptr));
    return Status::Ok();
  }
  template <typename T>
  Status Copy(const Buffer<T>& src, Buffer<T>& dst, size_t n) {
    if (n > src.size() || n > dst.size()) return OutOfRange("copy past the end of a device buffer");
    if (n == 0) return Status::Ok();
    VD_CL_CHECK(clEnqueueCopyBuffer(queue_, src.mem(), dst.mem(), 0, 0, n * sizeof(T), 0, nullptr, nullptr));
    return Status::Ok();
  }

  // Work-group size of every launch.
  static constexpr size_t kGroupSize = 64;
  // Items a work item of a laned kernel handles (VD_LANES of the program, shared/vd_compat.h):
  // the device's preferred float vector width on a CPU device (16 with AVX-512, 8 with AVX2),
  // 1 elsewhere; $VD_LANES (1, 4, 8 or 16) overrides it, for A/B runs and tests.
  int lanes() const { return lanes_; }
  // Blocks until every queued command finished (for timing and before host reads).
  Status Finish();

  // Device memory held by live buffers now and at most, bytes.
  size_t allocated_bytes() const { return allocated_bytes_; }
  size_t peak_bytes() const { return peak_bytes_; }

 private:
  template <class Signature>
  friend class Kernel;
  Context() = default;
  Status Build();
  // Runs kernel `name` over `items` work items (no-op when 0). Every kernel takes the item count
  // as its last argument (`int vd_items`, appended here) and returns early past it: the range is
  // padded to whole work-groups of a fixed size, so a device compiles one work-group variant per
  // kernel instead of one per distinct size (PoCL: ~0.1 s each, per frame for mesh-sized ranges).
  // Reached only through a typed Kernel handle (ocl/kernel.h), which checked the arguments and
  // passes its signature (one letter per argument, see FindKernel).
  // A laned kernel (per_item = lanes()) runs ceil(items / per_item) work items, each over per_item
  // consecutive items; vd_items is still `items`.
  template <typename... Args>
  Status Run(const char* name, const char* signature, size_t items, size_t per_item, const Args&... args) {
    if (items == 0) return Status::Ok();
    if (items > static_cast<size_t>(INT32_MAX)) return OutOfRange(std::string(name) + ": too many work items");
    VD_ASSIGN_OR_RETURN(cl_kernel k, FindKernel(name, signature));
    cl_uint index = 0;
    Status s = Status::Ok();
    (SetArg(k, index++, args, name, &s), ...);
    SetArg(k, index, static_cast<int32_t>(items), name, &s);
    VD_RETURN_IF_ERROR(s);
    // A laned work-group has kGroupSize / per_item work items: as many items as any other, so that
    // a small range still spreads over the device's cores.
    return Enqueue(k, name, (items + per_item - 1) / per_item, std::max<size_t>(kGroupSize / per_item, 1));
  }
  // The kernel `name` of the program, created once. Fails when the program's kernel disagrees with
  // `signature`, a letter per argument: 'w' a __global T*, 'r' a __global const T*, 's' a value.
  // Where the device reports no argument info only the count is compared.
  StatusOr<cl_kernel> FindKernel(const char* name, const char* signature);
  Status Enqueue(cl_kernel k, const char* name, size_t work_items, size_t local);

  template <typename T>
  static void SetArg(cl_kernel k, cl_uint i, const Buffer<T>& b, const char* name, Status* s) {
    if (!s->ok()) return;
    cl_mem m = b.mem();
    cl_int err = clSetKernelArg(k, i, sizeof(cl_mem), &m);
    if (err != CL_SUCCESS) *s = ClError(err, (std::string("clSetKernelArg ") + name + " #" + std::to_string(i)).c_str(), __FILE__, __LINE__);
  }
  template <typename T>
  static void SetArg(cl_kernel k, cl_uint i, const T& v, const char* name, Status* s) {
    static_assert(std::is_trivially_copyable_v<T>, "kernel arguments must be plain data");
    if (!s->ok()) return;
    cl_int err = clSetKernelArg(k, i, sizeof(T), &v);
    if (err != CL_SUCCESS) *s = ClError(err, (std::string("clSetKernelArg ") + name + " #" + std::to_string(i)).c_str(), __FILE__, __LINE__);
  }

  DeviceInfo device_;
  cl_context context_ = nullptr;
  cl_command_queue queue_ = nullptr;
  cl_program program_ = nullptr;
  // Per kernel name: the created kernel and its signature in the program (FindKernel's letters,
  // '?' for each argument whose kind the device does not report).
  std::map<std::string, std::pair<cl_kernel, std::string>> kernels_;
  std::mutex kernels_mutex_;
  int lanes_ = 1;
  size_t allocated_bytes_ = 0;
  size_t peak_bytes_ = 0;
  bool profile_enabled_ = std::getenv("VD_PROFILE_KERNELS") != nullptr;
  std::map<std::string, std::pair<double, long long>> profile_;
};

// The program source: embedded kernels with their shared headers inlined, or the files under
// $VD_KERNEL_DIR (kernels/*.cl and kernels/shared/*.h layout) when that variable is set.
StatusOr<std::string> AssembleProgramSource();

}  // namespace vd::ocl
