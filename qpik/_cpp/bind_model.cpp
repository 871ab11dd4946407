// Bindings of the model layer (qpik._engine.model).
#include "bind.hpp"

namespace nb = nanobind;

void bind_model(nb::module_& m) {
    (void)m;
}
