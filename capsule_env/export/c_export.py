"""A policy's deterministic action as dependency-free C99: ``NAME.c`` and ``NAME.h``.

``void capsule_policy(const float *obs, float *action)`` computes what the ONNX graph computes
(:mod:`capsule_env.export.network`): the observation normalisation in double precision (its
clip included), the network in float32 (weights as ``static const float`` arrays), the squash or
clip of SB3's ``predict`` and the clip to ``[-1, 1]``. No allocation (two stack buffers of the
widest layer), no global state, re-entrant; the only library function is ``tanhf`` from
``<math.h>`` (link with ``-lm``), and only when the network has a tanh.

A residual policy's ``capsule_policy`` gives the residual (its network's action), 0 when an
observation value is not finite (NaN, inf: the law alone, as
:class:`~capsule_env.agents.learning.residual.ResidualPolicy` acts; tested on the value's bits,
so that it holds under ``-ffast-math``, where a compiler may drop C99's ``isfinite``);
the file adds ``float capsule_combine(float law_action, float residual)``, the env's action
``clip(law_action + scale * residual, -1, 1)``, and, when its law has a C form
(:mod:`capsule_env.export.laws_c`), ``float capsule_law(const float *obs)`` (static) and
``void capsule_control(const float *obs, float *action)``: the law and the residual together.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

from capsule_env.export.network import (
    Activation,
    Dense,
    DeterministicActor,
    Hardtanh,
    Layer,
    Renorm,
)

__all__ = ["c_identifier", "c_header", "c_source"]

_HELPERS = {
    "dense": """static void dense(const float *weight, const float *bias, const float *x, float *y,
                  int n_out, int n_in)
{
    int i, j;
    for (i = 0; i < n_out; ++i) {
        const float *row = weight + i * n_in;
        float sum = 0.0f;
        for (j = 0; j < n_in; ++j) {
            sum += row[j] * x[j];
        }
        y[i] = sum + bias[i];
    }
}
""",
    "tanh": """static void tanh_layer(float *x, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        x[i] = tanhf(x[i]);
    }
}
""",
    "relu": """static void relu_layer(float *x, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        x[i] = x[i] > 0.0f ? x[i] : 0.0f;
    }
}
""",
    "clip": """static void clip_layer(float *x, int n, float low, float high)
{
    int i;
    for (i = 0; i < n; ++i) {
        x[i] = x[i] > high ? high : (x[i] < low ? low : x[i]);
    }
}
""",
    "renorm": """static void renorm_layer(float *x, int n, const float *mean, const float *std,
                         const float *scale, const float *bias)
{
    int i;
    for (i = 0; i < n; ++i) {
        x[i] = scale[i] * ((x[i] - mean[i]) / std[i]) + bias[i];
    }
}
""",
}


#: A residual policy's test of an observation value: not NaN or inf when its exponent bits are
#: not all ones (IEEE 754 binary32). An integer test, not C99's ``isfinite``, which a compiler
#: may assume true under ``-ffast-math`` / ``-Ofast`` (GCC does: the rule would be dropped).
_FINITE = """/* x is not NaN or inf: its exponent bits (IEEE 754 binary32) are not all ones; read as an
   integer so that -ffast-math, under which isfinite may be assumed true, keeps the test */
static int finite_value(float x)
{
    union {
        float f;
        uint32_t u;
    } bits;
    bits.f = x;
    return (bits.u & 0x7f800000u) != 0x7f800000u;
}
"""
#: A residual policy's first lines: a non-finite observation value gets the residual 0.
_NONFINITE = [
    "for (i = 0; i < N_OBS; ++i) {",
    "    if (!finite_value(obs[i])) { /* the network cannot read it: the law alone */",
    "        for (i = 0; i < N_ACTION; ++i) {",
    "            action[i] = 0.0f;",
    "        }",
    "        return;",
    "    }",
    "}",
]


def c_identifier(name: str) -> str:
    """``name`` as an upper-case C identifier part (header guard)."""
    return re.sub(r"[^A-Za-z0-9]", "_", name).upper()


def _float_literal(value: float) -> str:
    """A float32 as a C ``float`` literal: numpy's shortest repr that reads back as the same
    float32 (``0.1f``, ``1e-05f``, ``-2.0f``)."""
    return f"{np.float32(value)!s}f"


def _f32(values: np.ndarray) -> str:
    """float32 values as C literals (numpy's shortest repr that reads back as the same float)."""
    return ", ".join(_float_literal(v) for v in np.asarray(values, np.float32).ravel())


def _f64(values: np.ndarray) -> str:
    return ", ".join(repr(float(v)) for v in np.asarray(values, np.float64).ravel())


def _array(ctype: str, name: str, values: np.ndarray) -> str:
    text = _f32(values) if ctype == "float" else _f64(values)
    return f"static const {ctype} {name}[{np.asarray(values).size}] = {{{text}}};\n"


def _layer_code(k: int, layer: Layer, width: int, src: str, dst: str) -> tuple[str, str, int]:
    """(constants, the call, the new width) of layer ``k``; a dense layer writes ``dst``."""
    if isinstance(layer, Dense):
        n_out, n_in = layer.weight.shape
        consts = _array("float", f"L{k}_WEIGHT", layer.weight) + _array(
            "float", f"L{k}_BIAS", layer.bias
        )
        return consts, f"dense(L{k}_WEIGHT, L{k}_BIAS, {src}, {dst}, {n_out}, {n_in});", n_out
    if isinstance(layer, Activation):
        return "", f"{layer.kind}_layer({src}, {width});", width
    if isinstance(layer, Hardtanh):
        return (
            "",
            f"clip_layer({src}, {width}, {_float_literal(layer.low)}, {_float_literal(layer.high)});",
            width,
        )
    std = np.sqrt(layer.var.astype(np.float32) + np.float32(layer.eps))
    consts = "".join(_array("float", f"L{k}_{part.upper()}", values) for part, values in
                     (("mean", layer.mean), ("std", std), ("scale", layer.scale), ("bias", layer.bias)))  # fmt: skip
    call = f"renorm_layer({src}, {width}, L{k}_MEAN, L{k}_STD, L{k}_SCALE, L{k}_BIAS);"
    return consts, call, width


def _network(actor: DeterministicActor) -> tuple[list[str], list[str], str]:
    """(constants, statements, the buffer holding the output) of the layers, from buffer ``a``."""
    consts, calls = [], []
    buffers, width = ["a", "b"], actor.obs_size
    for k, layer in enumerate(actor.layers):
        const, call, width = _layer_code(k, layer, width, buffers[0], buffers[1])
        consts.append(const)
        calls.append(call)
        if isinstance(layer, Dense):
            buffers.reverse()
    return consts, calls, buffers[0]


def _helpers(layers: Sequence[Layer]) -> str:
    used = {"dense"}
    for layer in layers:
        if isinstance(layer, Activation):
            used.add(layer.kind)
        elif isinstance(layer, Hardtanh):
            used.add("clip")
        elif isinstance(layer, Renorm):
            used.add("renorm")
    return "\n".join(_HELPERS[h] for h in ("dense", "tanh", "relu", "clip", "renorm") if h in used)


def _normalise_lines(actor: DeterministicActor) -> tuple[str, list[str]]:
    norm = actor.normaliser
    if norm is None:
        return "", ["for (i = 0; i < N_OBS; ++i) {", "    a[i] = obs[i];", "}"]
    consts = (_array("double", "OBS_MEAN", norm.mean) + _array("double", "OBS_STD", norm.std)
              + f"static const double OBS_CLIP = {float(norm.clip)!r};\n")  # fmt: skip
    return consts, [
        "for (i = 0; i < N_OBS; ++i) {",
        "    double z = ((double)obs[i] - OBS_MEAN[i]) / OBS_STD[i];",
        "    z = z > OBS_CLIP ? OBS_CLIP : (z < -OBS_CLIP ? -OBS_CLIP : z);",
        "    a[i] = (float)z;",
        "}",
    ]


def _output_lines(actor: DeterministicActor, out: str) -> tuple[str, list[str]]:
    consts = _array("float", "ACTION_LOW", actor.low) + _array("float", "ACTION_HIGH", actor.high)
    step = [
        "    float v = tanhf(" + out + "[i]);" if actor.tanh_output else f"    float v = {out}[i];"
    ]
    if actor.rescale:  # SB3's unscale_action, in float32
        step.append(
            "    v = ACTION_LOW[i] + (0.5f * (v + 1.0f) * (ACTION_HIGH[i] - ACTION_LOW[i]));"
        )
    else:
        step.append(
            "    v = v > ACTION_HIGH[i] ? ACTION_HIGH[i] : (v < ACTION_LOW[i] ? ACTION_LOW[i] : v);"
        )
    step.append("    action[i] = v > 1.0f ? 1.0f : (v < -1.0f ? -1.0f : v);")
    return consts, ["for (i = 0; i < N_ACTION; ++i) {", *step, "}"]


def _residual_code(scale: float, law_code: str | None) -> str:
    combine = f"""
float capsule_combine(float law_action, float residual)
{{
    double total = (double)law_action + {float(scale)!r} * (double)residual;
    total = total > 1.0 ? 1.0 : (total < -1.0 ? -1.0 : total);
    return (float)total;
}}
"""
    if law_code is None:
        return combine
    control = """
void capsule_control(const float *obs, float *action)
{
    float residual;
    capsule_policy(obs, &residual);
    action[0] = capsule_combine(capsule_law(obs), residual);
}
"""
    return combine + "\n" + law_code + control


def c_source(actor: DeterministicActor, name: str, banner: str, residual_scale: float | None = None,
             law_code: str | None = None) -> str:  # fmt: skip
    """``NAME.c`` (module docstring); ``banner``: the comment lines on top (provenance)."""
    norm_consts, norm_lines = _normalise_lines(actor)
    net_consts, net_lines, out = _network(actor)
    out_consts, out_lines = _output_lines(actor, out)
    widest = max([actor.obs_size] + [layer.weight.shape[0] for layer in actor.layers
                                     if isinstance(layer, Dense)])  # fmt: skip
    residual = residual_scale is not None
    body = ["float a[WIDTH], b[WIDTH];", "int i;", *(_NONFINITE if residual else []),
            *norm_lines, *net_lines, *out_lines]  # fmt: skip
    parts = [
        banner, f'#include "{name}.h"\n\n#include <math.h>\n'
        + ("#include <stdint.h>\n" if residual else ""),
        f"#define N_OBS {actor.obs_size}\n#define N_ACTION {actor.action_size}\n"
        f"#define WIDTH {widest}\n",
        norm_consts + "".join(net_consts) + out_consts,
        _helpers(actor.layers) + (f"\n{_FINITE}" if residual else ""),
        "void capsule_policy(const float *obs, float *action)\n{\n"
        + "".join(f"    {line}\n" for line in body) + "}\n",
    ]  # fmt: skip
    if residual_scale is not None:  # the type checker narrows on this test
        parts.append(_residual_code(residual_scale, law_code))
    return "\n".join(parts)


def c_header(actor: DeterministicActor, name: str, banner: str, residual: bool, law: bool,
             period_s: float) -> str:  # fmt: skip
    """``NAME.h``: the functions of ``NAME.c`` and the sizes."""
    guard = f"CAPSULE_POLICY_{c_identifier(name)}_H"
    what = ("its residual; 0 when an obs value is NaN or inf (the law alone)" if residual
            else "the policy's deterministic action")  # fmt: skip
    decls = [f"/* {what} */", "void capsule_policy(const float *obs, float *action);"]
    if residual:
        decls += ["/* the env's action: clip(law_action + scale * residual, -1, 1) */",
                  "float capsule_combine(float law_action, float residual);"]  # fmt: skip
    if law:
        decls += ["/* the base law and the residual together: the env's action */",
                  "void capsule_control(const float *obs, float *action);"]  # fmt: skip
    return (
        f"{banner}#ifndef {guard}\n#define {guard}\n\n"
        f"#define CAPSULE_POLICY_OBS_SIZE {actor.obs_size}\n"
        f"#define CAPSULE_POLICY_ACTION_SIZE {actor.action_size}\n"
        f"#define CAPSULE_POLICY_PERIOD_S {period_s!r}\n\n"
        "#ifdef __cplusplus\nextern \"C\" {\n#endif\n\n" + "\n".join(decls) + "\n\n"
        "#ifdef __cplusplus\n}\n#endif\n\n" f"#endif /* {guard} */\n"
    )  # fmt: skip
