#include "lblight/backend/backend.h"

namespace lblight {

const char* to_string(Precision p) {
  switch (p) {
    case Precision::Float32: return "float32";
    case Precision::Float64: return "float64";
    case Precision::Float16: return "float16";
  }
  return "?";
}

}  // namespace lblight
