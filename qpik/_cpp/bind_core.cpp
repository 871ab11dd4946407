// Bindings of the core layer (qpik._engine.core).
#include "bind.hpp"

namespace nb = nanobind;

void bind_core(nb::module_& m) {
    (void)m;
}
