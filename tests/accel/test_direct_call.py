"""`direct_call`: the generated wrapper read line by line into a plan, or refused with the line it does not know;
the forwarding function's constants exactly as the package's memory holds them."""

import pytest
import torch

from aerobench.accel.direct_call import (
    Source,
    UnsupportedPackage,
    _literal,
    forwarding_source,
    memory_order,
    plan_from_wrapper,
)

# the shape of inductor's stack-allocating CPU wrapper (torch 2.11), cut down to two inputs, a constant, a stack
# buffer with an alias into it and another name for it (reused), and one in-place kernel
RUN_IMPL = """
void AOTInductorModel::run_impl(
    AtenTensorHandle*
        input_handles, // array of input AtenTensorHandle; handles
                        // are stolen; the array itself is borrowed
    DeviceStreamType stream,
    AOTIProxyExecutorHandle proxy_executor
) {

__check_inputs_outputs(input_handles, output_handles);

    auto inputs = steal_from_raw_handles_to_raii_handles(input_handles, 2);
    auto arg0_1 = std::move(inputs[0]);
    auto arg1_1 = std::move(inputs[1]);
    auto _tensor_constant1 = constants_->at(0);
    inputs.clear();
    [[maybe_unused]] auto& kernels = static_cast<AOTInductorModelKernels&>(*this->kernels_.get());
    static constexpr int64_t int_array_0[] = {1L, 9L};
    static constexpr int64_t int_array_1[] = {9L, 1L};
    float buf10_storage[9];
    ArrayRefTensor<float> buf10(buf10_storage, int_array_0, int_array_1, cached_torch_device_type_cpu, this->device_idx_);
    static constexpr int64_t int_array_4[] = {1L, 1L};
    auto buf3 = wrap_with_raii_handle_if_needed(reinterpret_tensor_wrapper(buf10, 2, int_array_4, int_array_1, 2L));  // alias
    auto buf4 = wrap_with_raii_handle_if_needed(reinterpret_tensor_wrapper(buf3, 2, int_array_4, int_array_1, 3L));  // alias
    auto* var_0 = get_data_ptr_wrapper(arg1_1);
    auto* var_1 = get_data_ptr_wrapper(_tensor_constant1);
    auto buf11 = std::move(buf10);  // reuse
    auto* var_2 = get_data_ptr_wrapper(buf11);
    auto* var_3 = get_data_ptr_wrapper(buf4);
    auto* var_4 = get_data_ptr_wrapper(arg0_1);
    cpp_fused_add_0((const float*)(var_0), (const float*)(var_1), (float*)(var_2), (float*)(var_3), (float*)(var_4));
    arg0_1.reset();
    arg1_1.reset();
} // AOTInductorModel::run_impl
"""


def test_every_line_of_run_impl_becomes_a_kernel_argument_with_its_source():
    plan = plan_from_wrapper(RUN_IMPL)
    assert plan.kernel == "cpp_fused_add_0" and plan.num_inputs == 2
    assert plan.buffers == {"buf10": ("float", 9)} and plan.constants == {"_tensor_constant1": 0}
    assert plan.arguments == (
        ("const float*", Source("input", "1")),
        ("const float*", Source("constant", "_tensor_constant1")),
        ("float*", Source("buffer", "buf10", 0)),
        ("float*", Source("buffer", "buf10", 5)),  # an alias of an alias: the offsets add up
        ("float*", Source("input", "0")),
    )


@pytest.mark.parametrize("change, reason", [
    (("    arg0_1.reset();", "    aoti_torch_cpu_mm(buf10, arg0_1);\n    arg0_1.reset();"), "does more than one"),
    (("    arg0_1.reset();", "    cpp_fused_add_0((float*)(var_4));\n    arg0_1.reset();"), "more than one kernel"),
    (("    arg0_1.reset();", "    output_handles[0] = buf10.release();\n    arg0_1.reset();"), "does more than one"),
    (("get_data_ptr_wrapper(buf4)", "get_data_ptr_wrapper(buf99)"), "buf99 is not an input"),
    (("void AOTInductorModel::run_impl(", "void run("), "no AOTInductorModel::run_impl"),
])
def test_anything_else_in_run_impl_is_refused_with_the_line(change, reason):
    with pytest.raises(UnsupportedPackage, match=reason):
        plan_from_wrapper(RUN_IMPL.replace(*change))


def test_the_forwarding_function_holds_the_constants_as_they_lie_in_memory():
    plan = plan_from_wrapper(RUN_IMPL)
    constant = torch.tensor([[0.1, 1 / 3], [-2.5, 7.0]]).t()  # a transposed view: memory order is not index order
    source, params = forwarding_source(plan, [torch.float32, torch.float32], {"_tensor_constant1": constant})
    assert params == ["float*", "float*"]
    assert torch.equal(memory_order(constant), torch.tensor([0.1, 1 / 3, -2.5, 7.0]))
    literals = source.split("_tensor_constant1[] = {")[1].split("}")[0].split(", ")
    assert [float.fromhex(v.rstrip("f")) for v in literals] == memory_order(constant).tolist()
    assert "float buf10[9];" in source
    assert "cpp_fused_add_0((const float*)(in1 + 0), (const float*)(_tensor_constant1 + 0), (float*)(buf10 + 0), " \
           "(float*)(buf10 + 5), (float*)(in0 + 0));" in source
    with pytest.raises(UnsupportedPackage, match="no value for the constant"):
        forwarding_source(plan, [torch.float32, torch.float32], {})
    with pytest.raises(UnsupportedPackage, match="inputs do not match"):
        forwarding_source(plan, [torch.float32], {"_tensor_constant1": constant})


def test_literals_are_exact_and_a_non_finite_constant_is_refused():
    for value in (0.1, -1 / 3, 1e-38, 3.4e38):
        single = torch.tensor(value).item()  # the float32 value
        assert float.fromhex(_literal(single, "float").rstrip("f")) == single
    assert _literal(True, "bool") == "true" and _literal(7, "int64_t") == "7LL"
    with pytest.raises(UnsupportedPackage, match="not finite"):
        _literal(float("nan"), "float")

