// qpik._engine: the compiled engine, one submodule per layer of the Python package
// (docs/architecture.md). Each layer's bindings live in its own bind_*.cpp.
#include <nanobind/nanobind.h>

namespace nb = nanobind;

void bind_core(nb::module_& m);
void bind_model(nb::module_& m);
void bind_tasks(nb::module_& m);
void bind_limits(nb::module_& m);
void bind_diffik(nb::module_& m);
void bind_igm(nb::module_& m);

NB_MODULE(_engine, m) {
    m.doc() = "qpik's compiled engine (C++17, built when the package is installed).";
    nb::module_ core = m.def_submodule("core", "Linear algebra, the QP solver and the cascade.");
    bind_core(core);
    nb::module_ model = m.def_submodule("model", "Chain kinematics and rotations.");
    bind_model(model);
    nb::module_ tasks = m.def_submodule("tasks", "SE(3) maps and the frame task's rows.");
    bind_tasks(tasks);
    nb::module_ limits = m.def_submodule(
        "limits", "Culling of collision pairs, their contact rows and the support polygon's hull.");
    bind_limits(limits);
    nb::module_ diffik = m.def_submodule("diffik", "The one-call differential IK step.");
    bind_diffik(diffik);
    nb::module_ igm = m.def_submodule("igm", "The full-IK loop and its box QP.");
    bind_igm(igm);
}
