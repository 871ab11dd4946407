// Bindings of the igm layer (qpik._engine.igm).
#include "bind.hpp"

namespace nb = nanobind;

void bind_igm(nb::module_& m) {
    (void)m;
}
