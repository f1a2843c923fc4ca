#pragma once
// Typed kernel handles: each kernel of the program is declared once with its signature, e.g.
//   inline constexpr Kernel<void(const Buffer<uint16_t>& raw, Buffer<float>& depth, float scale)>
//       kScale{"vd_scale"};
// and a launch kScale(ctx, items, raw, depth, 0.001f) that does not match it does not compile.
// The signature is a function type so that the handle names its parameters as the .cl does.
// A `Buffer<T>&` parameter (the kernel writes it: `__global T*`) takes only a non-const Buffer<T>;
// a `const Buffer<T>&` (`__global const T*`) takes any Buffer<T>; a scalar parameter takes exactly
// its type (no int -> float, no int -> uint). The `int vd_items` every kernel ends with is added
// by Context::Run. The call operator is constrained rather than asserting, so a test can check a
// launch with std::is_invocable_v.
#include <cstddef>
#include <type_traits>

#include "ocl/ocl.h"

namespace vd::ocl {
namespace kernel_detail {

template <class T>
using Bare = std::remove_cv_t<std::remove_reference_t<T>>;

template <class T>
struct IsBuffer : std::false_type {};
template <class T>
struct IsBuffer<Buffer<T>> : std::true_type {};

// Whether an argument of type A (as a forwarding reference deduces it) may pass for parameter P.
template <class P, class A>
inline constexpr bool kAccepts = std::is_same_v<Bare<A>, P>;
template <class T, class A>
inline constexpr bool kAccepts<Buffer<T>&, A> = std::is_same_v<A, Buffer<T>&>;
template <class T, class A>
inline constexpr bool kAccepts<const Buffer<T>&, A> = std::is_same_v<Bare<A>, Buffer<T>>;

template <class... T>
struct List {};
// Same count first, so the pairwise test never expands packs of different lengths.
template <class Params, class Args, class = void>
struct AcceptsAll : std::false_type {};
template <class... Ps, class... As>
struct AcceptsAll<List<Ps...>, List<As...>, std::enable_if_t<sizeof...(Ps) == sizeof...(As)>>
    : std::bool_constant<(kAccepts<Ps, As> && ...)> {};

// How the program sees a parameter: 'w' a __global T*, 'r' a __global const T*, 's' a value.
template <class P>
inline constexpr char kArgKind = 's';
template <class T>
inline constexpr char kArgKind<Buffer<T>&> = 'w';
template <class T>
inline constexpr char kArgKind<const Buffer<T>&> = 'r';

template <class P>
inline constexpr bool kValidParam =
    std::is_reference_v<P> ? IsBuffer<Bare<P>>::value && (std::is_const_v<std::remove_reference_t<P>> || kArgKind<P> == 'w')
                           : std::is_trivially_copyable_v<P> && !std::is_pointer_v<P> && !IsBuffer<P>::value;

}  // namespace kernel_detail

// Marks a handle whose kernel runs VD_LANES items per work item (Context::lanes()).
struct Laned {};
inline constexpr Laned kLaned{};

template <class... Params>
class Kernel<void(Params...)> {
  static_assert((kernel_detail::kValidParam<Params> && ...),
                "kernel parameters are Buffer<T>& (written), const Buffer<T>& (read) or plain values");

 public:
  explicit constexpr Kernel(const char* name) : name_(name) {}
  constexpr Kernel(const char* name, Laned) : name_(name), laned_(true) {}
  constexpr const char* name() const { return name_; }

  // Runs the kernel over `items` items (none when 0): one work item each, or one lane each when the
  // handle is laned; see Context::Run.
  template <class... Args,
            std::enable_if_t<kernel_detail::AcceptsAll<kernel_detail::List<Params...>, kernel_detail::List<Args&&...>>::value,
                             int> = 0>
  Status operator()(Context& ctx, size_t items, Args&&... args) const {
    return ctx.Run(name_, kSignature, items, laned_ ? size_t(ctx.lanes()) : size_t(1), args...);
  }

 private:
  // One kArgKind letter per parameter and 's' for vd_items: compared with the program's view of
  // the kernel, so a handle that disagrees with its .cl fails at its first launch.
  static constexpr char kSignature[] = {kernel_detail::kArgKind<Params>..., 's', '\0'};
  const char* name_;
  bool laned_ = false;
};

}  // namespace vd::ocl
