// Checking the errors that bad input (or a cancelled run) must raise, for the tests.
#pragma once

#include <catch2/catch.hpp>

#include <stdexcept>
#include <string>
#include <utility>

#include "lblight/core/error.h"

namespace lblight::test {

// Runs `f`, which must throw an lblight::Error of `category` whose message contains `mention`,
// and returns that error for further checks (its location, other words). Fails the test case
// when `f` throws nothing.
template <class F>
Error expect_error(ErrorCategory category, F&& f, const std::string& mention = "") {
  try {
    f();
  } catch (const Error& e) {
    INFO(e.what());
    CHECK(e.category() == category);
    CHECK(std::string(e.what()).find(mention) != std::string::npos);
    return e;
  }
  FAIL("no error thrown" << (mention.empty() ? std::string() : ": expected one mentioning \"" + mention + "\""));
  throw std::logic_error("unreachable: FAIL ends the test case");
}

// The same for an input error (exit code 2).
template <class F>
Error expect_invalid_input(F&& f, const std::string& mention) {
  return expect_error(ErrorCategory::InvalidInput, std::forward<F>(f), mention);
}

}  // namespace lblight::test
