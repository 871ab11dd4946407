// Bindings of the diffik layer (qpik._engine.diffik).
#include "bind.hpp"

namespace nb = nanobind;

void bind_diffik(nb::module_& m) {
    (void)m;
}
