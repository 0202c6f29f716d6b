#include "python/bindings.hpp"

namespace wiretape::python {

void bind_session(nanobind::module_&) {}

}  // namespace wiretape::python
