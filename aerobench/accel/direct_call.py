"""An ahead-of-time package's one fused kernel, called straight from Python without AOTInductor's runner.

A CPU package of a small kernel is one generated C function (`cpp_fused_..._0`, raw pointers in) inside a generic
entry: `loader.run(list)` wraps each input in a new tensor handle, takes the model container's lock, wraps the
stack buffers as array-ref tensors, calls the function, then releases it all, and pybind converts the lists both ways.
For the 240 Hz flight step that entry costs about 3 us of a 3.5 us call back to back. On this CPU machine every call
made right after a physics step runs cold (`bench/call_warmth.py`), so all the code that entry touches is paid
for again at each of the 12 calls per control step: 14 us a call in the loop against 5 us for the function alone
(docs/performance.md).

`direct_entry` reads the package's own generated C++: the wrapper's `run_impl` says which input, constant, stack
buffer or offset into one the kernel gets as each argument. It builds a forwarding function with those buffers as
locals and the constants as literals, compiled with inductor's own Python bindings for C++ kernels (as inductor's
Python wrapper calls its CPU kernels: one C call that takes each tensor's data pointer). The call takes the
package's inputs in order, contiguous and of the shapes it was built for, and returns nothing: only a package whose
kernel writes its results into its inputs qualifies (no outputs to hand back). Anything else in `run_impl` (a
second kernel, an ATen call, a heap buffer, a size argument) means the package is not of this form and
`UnsupportedPackage` says which line; `kernels.Kernel` then keeps the runner. The parse is of torch's generated
code, so `Kernel` also checks the entry against the runner on the first inputs before using it.
"""

from __future__ import annotations

import re
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import torch

# the C type a kernel takes for a tensor of each dtype
C_TYPES = {torch.float32: "float", torch.float64: "double", torch.int64: "int64_t", torch.int32: "int32_t",
           torch.bool: "bool"}
ENTRY = "kernel"  # the function name inductor's Python bindings call


class UnsupportedPackage(ValueError):
    """The package is not one in-place kernel this module can call directly."""


@dataclass(frozen=True)
class Source:
    """Where one pointer argument of the kernel comes from: an input, a constant or a stack buffer, at an offset in
    elements."""

    kind: str  # "input", "constant" or "buffer"
    name: str  # the input's position (as a string), the constant's or the buffer's name
    offset: int = 0


@dataclass(frozen=True)
class CallPlan:
    """What the wrapper's `run_impl` does: its kernel, with the source of each argument, its inputs, stack buffers
    and constants."""

    kernel: str
    arguments: tuple[tuple[str, Source], ...]  # (the C type of the argument, where it points)
    num_inputs: int
    buffers: dict[str, tuple[str, int]]  # storage -> (C type, elements)
    constants: dict[str, int]  # name -> index in the package's constants


_LINE_PATTERNS = {
    "inputs": re.compile(r"auto inputs = steal_from_raw_handles_to_raii_handles\(input_handles, (\d+)\);"),
    "input": re.compile(r"auto (\w+) = std::move\(inputs\[(\d+)\]\);"),
    "constant": re.compile(r"auto (\w+) = constants_->at\((\d+)\);"),
    "storage": re.compile(r"([\w:]+) (\w+)_storage\[(\d+)\];"),
    "array_ref": re.compile(r"ArrayRefTensor<[\w:]+> (\w+)\((\w+)_storage, int_array_\d+, int_array_\d+, "
                            r"cached_torch_device_type_cpu, this->device_idx_\);"),
    "alias": re.compile(r"auto (\w+) = wrap_with_raii_handle_if_needed\(reinterpret_tensor_wrapper\((\w+), \d+, "
                        r"int_array_\d+, int_array_\d+, (\d+)L\)\);(\s*// alias)?"),
    "reuse": re.compile(r"auto (\w+) = std::move\((\w+)\);\s*// reuse"),
    "pointer": re.compile(r"auto\* (var_\d+) = get_data_ptr_wrapper\((\w+)\);"),
    "call": re.compile(r"(cpp_fused_\w+)\(((?:\((?:const )?[\w:]+\*\)\(var_\d+\)(?:, )?)+)\);"),
}
_HARMLESS = re.compile(
    r"(static constexpr int64_t int_array_\d+\[\] = \{[\dL, ]*\};"
    r"|\[\[maybe_unused\]\] auto& kernels = static_cast<AOTInductorModelKernels&>\(\*this->kernels_\.get\(\)\);"
    r"|inputs\.clear\(\);|\w+\.reset\(\);|__check_inputs_outputs\(input_handles, output_handles\);|\{|\}|//.*|)")


def run_impl_body(wrapper_cpp: str) -> list[str]:
    """The statements of the wrapper's `AOTInductorModel::run_impl`, one per line as inductor writes them."""
    start = wrapper_cpp.find("void AOTInductorModel::run_impl(")
    end = wrapper_cpp.find("} // AOTInductorModel::run_impl", start)
    if start < 0 or end < 0:
        raise UnsupportedPackage("no AOTInductorModel::run_impl in the wrapper")
    body = wrapper_cpp[wrapper_cpp.index(") {", start) + 3:end]
    return [line.strip() for line in body.splitlines()]


def plan_from_wrapper(wrapper_cpp: str) -> CallPlan:
    """Every line of `run_impl` accounted for, or `UnsupportedPackage` naming the first one that is not."""
    names: dict[str, Source] = {}  # a name in run_impl -> what its data pointer is
    pointers: dict[str, Source] = {}
    buffers: dict[str, tuple[str, int]] = {}
    constants: dict[str, int] = {}
    num_inputs, call = None, None
    for line in run_impl_body(wrapper_cpp):
        kind, match = next(((k, m) for k, p in _LINE_PATTERNS.items() if (m := p.fullmatch(line))), (None, None))
        if kind is None:
            if _HARMLESS.fullmatch(line):
                continue
            raise UnsupportedPackage(f"run_impl does more than one in-place kernel: {line[:120]!r}")
        if kind == "inputs":
            num_inputs = int(match[1])
        elif kind == "input":
            names[match[1]] = Source("input", match[2])
        elif kind == "constant":
            names[match[1]] = Source("constant", match[1])
            constants[match[1]] = int(match[2])
        elif kind == "storage":
            buffers[match[2]] = (match[1], int(match[3]))
        elif kind == "array_ref":
            if match[2] not in buffers:
                raise UnsupportedPackage(f"an array-ref tensor over unknown storage: {line[:120]!r}")
            names[match[1]] = Source("buffer", match[2])
        elif kind == "alias":
            base = _known(names, match[2], line)
            names[match[1]] = Source(base.kind, base.name, base.offset + int(match[3]))
        elif kind == "reuse":  # a dead buffer's storage taken over by a new one
            names[match[1]] = _known(names, match[2], line)
        elif kind == "pointer":
            pointers[match[1]] = _known(names, match[2], line)
        else:
            if call is not None:
                raise UnsupportedPackage("run_impl calls more than one kernel")
            args = re.findall(r"\(((?:const )?[\w:]+\*)\)\((var_\d+)\)", match[2])
            call = (match[1], tuple((c_type, _known(pointers, var, line)) for c_type, var in args))
    if num_inputs is None or call is None:
        raise UnsupportedPackage("run_impl has no inputs or no kernel call")
    return CallPlan(call[0], call[1], num_inputs, buffers, constants)


def _known(names: dict[str, Source], name: str, line: str) -> Source:
    if name not in names:
        raise UnsupportedPackage(f"{name} is not an input, a constant or a buffer: {line[:120]!r}")
    return names[name]


def _literal(value: float | int | bool, c_type: str) -> str:
    if c_type == "bool":
        return "true" if value else "false"
    if c_type in ("float", "double"):
        value = float(value)
        if value != value or value in (float("inf"), float("-inf")):
            raise UnsupportedPackage("a constant that is not finite")
        return value.hex() + ("f" if c_type == "float" else "")
    return f"{int(value)}LL"


def memory_order(t: torch.Tensor) -> torch.Tensor:
    """A dense tensor's elements in the order they lie in memory (what a kernel reading raw memory sees)."""
    order = sorted(range(t.ndim), key=lambda d: -t.stride(d))
    permuted = t.permute(order)
    expected = 1
    for size, stride in zip(reversed(permuted.shape), reversed(permuted.stride())):
        if size > 1 and stride != expected:
            raise UnsupportedPackage("a constant that is not dense in memory")
        expected *= size
    return permuted.contiguous().flatten()


def forwarding_source(plan: CallPlan, input_dtypes: Sequence[torch.dtype],
                      constants: dict[str, torch.Tensor]) -> tuple[str, list[str]]:
    """The C++ of `ENTRY(inputs...)`: the plan's stack buffers as locals, its constants as static literals, one
    call of the kernel. Returns the source and the entry's argument types (for the Python binding)."""
    if len(input_dtypes) != plan.num_inputs or any(d not in C_TYPES for d in input_dtypes):
        raise UnsupportedPackage("the inputs do not match the package")
    params = [f"{C_TYPES[d]}*" for d in input_dtypes]
    lines = [f"extern \"C\" void {ENTRY}({', '.join(f'{p} in{i}' for i, p in enumerate(params))}) {{"]
    for name in plan.constants:
        if name not in constants or constants[name].dtype not in C_TYPES:
            raise UnsupportedPackage(f"no value for the constant {name} (or one of a type without a C type here)")
        c_type = C_TYPES[constants[name].dtype]
        values = ", ".join(_literal(v, c_type) for v in memory_order(constants[name]).tolist())
        lines.append(f"    alignas(64) static const {c_type} {name}[] = {{{values}}};")
    for name, (c_type, size) in plan.buffers.items():
        lines.append(f"    alignas(64) {c_type} {name}[{size}];")
    args = []
    for c_type, source in plan.arguments:
        base = f"in{source.name}" if source.kind == "input" else source.name
        args.append(f"({c_type})({base} + {source.offset})")
    lines += [f"    {plan.kernel}({', '.join(args)});", "}"]
    return "\n".join(lines), params


def read_package_sources(package: Path) -> tuple[str, str]:
    """The generated wrapper and kernel C++ of an AOTInductor package (`.pt2`)."""
    with zipfile.ZipFile(package) as z:
        wrapper = [n for n in z.namelist() if n.endswith(".wrapper.cpp")]
        kernel = [n for n in z.namelist() if n.endswith(".kernel.cpp")]
        if len(wrapper) != 1 or len(kernel) != 1:
            raise UnsupportedPackage("the package does not hold one wrapper and one kernel source")
        return z.read(wrapper[0]).decode(), z.read(kernel[0]).decode()


def direct_entry(package: Path, library: Path, input_dtypes: Sequence[torch.dtype],
                 options: dict) -> Callable[..., None]:
    """The package's kernel as a Python function of its inputs (tensors, in order), which writes its results into
    them. `library` is the package's loaded model library (its constants are read from it); `options` the inductor
    options it was built with. Raises `UnsupportedPackage`, or the compiler's error."""
    from torch._inductor.codecache import CppPythonBindingsCodeCache

    wrapper, kernel = read_package_sources(package)
    # inductor's comments (the build's commands, with the building machine's paths) left out: the same kernel is
    # the same source wherever it was built, and found in the compiler's cache
    kernel = "\n".join(line for line in kernel.splitlines() if not line.lstrip().startswith("//"))
    plan = plan_from_wrapper(wrapper)
    constants = {}
    if plan.constants:
        runner = torch._C._aoti.AOTIModelContainerRunnerCpu(str(library), 1)
        constants = {name: t.clone() for name, t in runner.extract_constants_map(False).items()}
    source, params = forwarding_source(plan, input_dtypes, constants)
    if re.search(rf"\b{ENTRY}\b", kernel):
        raise UnsupportedPackage(f"the kernel source already names {ENTRY}")
    with torch._inductor.config.patch(options):
        return CppPythonBindingsCodeCache.load_pybinding(params, kernel + "\n" + source)
