#include "python/bindings.hpp"

namespace wiretape::python {

void bind_bridge(nanobind::module_&) {}

}  // namespace wiretape::python
