// Checking the errors that bad input must raise, for the tests.
#pragma once

#include <catch2/catch.hpp>

#include <stdexcept>
#include <string>

#include "lblight/core/error.h"

namespace lblight::test {

// Runs `f`, which must throw an InvalidInput lblight::Error whose message contains `mention`, and
// returns that error for further checks (its location, other words). Fails the test case when `f`
// throws nothing.
template <class F>
Error expect_invalid_input(F&& f, const std::string& mention) {
  try {
    f();
  } catch (const Error& e) {
    INFO(e.what());
    CHECK(e.category() == ErrorCategory::InvalidInput);
    CHECK(std::string(e.what()).find(mention) != std::string::npos);
    return e;
  }
  FAIL("accepted: expected an input error mentioning \"" << mention << "\"");
  throw std::logic_error("unreachable: FAIL ends the test case");
}

}  // namespace lblight::test
