#include "python/bindings.hpp"

namespace wiretape::python {

void bind_port(nanobind::module_&) {}

}  // namespace wiretape::python
