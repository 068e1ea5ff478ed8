#!/usr/bin/env python3
"""NVIDIA's HDR-FLIP on the image pair of trainer/src/metrics/flip.rs `reference_tests`, the value
that test checks flip-rs against:

    pip install flip-evaluator numpy
    python3 benches/flip_reference.py     # prints the mean and the exposure parameters

The pair is built from a formula whose values are exact in f32 (multiples of 1/64 and a bright spot),
so that numpy and Rust hold the very same pixels.
"""
import numpy as np
import flip_evaluator as flip

N = 48


def pair():
    y, x = np.mgrid[0:N, 0:N]
    ref = np.zeros((N, N, 3), np.float32)
    test = np.zeros((N, N, 3), np.float32)
    for c in range(3):
        ref[..., c] = (((x * 7 + y * 3 + c * 5) % 32) + 1) / 64.0
        test[..., c] = (((x * 5 + y * 11 + c * 3) % 32) + 1) / 64.0
    spot = (x - 20) ** 2 + (y - 28) ** 2 < 16
    ref[spot] = 8.0
    test[spot] = 6.0
    # The test equals the reference on the left half, so the error has structure.
    test[:, : N // 2] = ref[:, : N // 2]
    return ref, test


if __name__ == "__main__":
    ref, test = pair()
    _, mean, params = flip.evaluate(ref, test, "HDR", applyMagma=False)
    print(repr(mean), params)
