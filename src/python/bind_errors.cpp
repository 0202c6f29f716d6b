#include "python/bindings.hpp"

namespace wiretape::python {

void bind_errors(nanobind::module_&) {}

}  // namespace wiretape::python
