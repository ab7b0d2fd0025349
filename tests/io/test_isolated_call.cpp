// run_isolated (core/isolated_call.h): a child's crash or exception comes back as an outcome, and
// its memory cap holds (docs/reliability.md: the isolated .vdb reader may take 512 MiB plus 256x
// the file, never the machine's memory). The cap was once never set: /proc/self/status was read
// as "key number" pairs and its first line ended the search.
#include <catch2/catch.hpp>

#include <csignal>
#include <cstring>
#include <new>
#include <stdexcept>
#include <vector>

#include "lblight/core/isolated_call.h"

using namespace lblight;

namespace {

// As core/isolated_call.cpp decides: under AddressSanitizer there is no cap (it reserves terabytes
// of address space), and ASan handles SIGSEGV itself.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAsan = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAsan = true;
#else
constexpr bool kAsan = false;
#endif
#else
constexpr bool kAsan = false;
#endif

}  // namespace

TEST_CASE("run_isolated: outcomes, and the memory cap holds in the child", "[io][isolated]") {
  CHECK(run_isolated([] {}, 10).kind == IsolatedOutcome::Kind::Ok);
  const IsolatedOutcome threw = run_isolated([] { throw std::runtime_error("bad header"); }, 10);
  CHECK(threw.kind == IsolatedOutcome::Kind::Threw);
  CHECK(threw.message == "bad header");
  // 16 MiB within a 256 MiB cap; 1 GiB, touched, beyond it
  const auto allocate = [](std::size_t bytes) {
    return [bytes] {
      std::vector<char> block(bytes);
      std::memset(block.data(), 1, block.size());
      if (block[bytes / 2] != 1) throw std::logic_error("unreachable");
    };
  };
  CHECK(run_isolated(allocate(16u << 20), 30, {}, 256u << 20).kind == IsolatedOutcome::Kind::Ok);
  if (kAsan) {
    WARN("AddressSanitizer build: no memory cap and no crash check (ASan owns SIGSEGV)");
    return;
  }
  CHECK(run_isolated([] { std::raise(SIGSEGV); }, 10).kind == IsolatedOutcome::Kind::Crashed);
  const IsolatedOutcome big = run_isolated(allocate(std::size_t{1} << 30), 30, {}, 256u << 20);
  INFO(big.message);
  CHECK(big.kind != IsolatedOutcome::Kind::Ok);  // bad_alloc (Threw) or killed (Crashed)
}
