"""A line-by-line numpy transcription of the paper's Eq. (1), (3), (4), (5).

Independent of brdfjax's rearranged formulas: valid at generic points only (it divides by
zero at the specular point and at grazing angles, exactly where the paper's form breaks).
"""

import numpy as np

SIGMA_SPH, SIGMA_R, U_SPH, V_SPH = 0.0136, 0.0141, 9.0, 1.0


def brdf(kb, kr, a, b, kd, ti, tr, pr):
    cos_g = np.sqrt(0.5 * (np.cos(ti) * np.cos(tr) + np.sin(ti) * np.sin(tr) * np.cos(pr) + 1))
    cos_alpha = (np.cos(ti) + np.cos(tr)) / (2 * cos_g)
    alpha = np.arccos(np.clip(cos_alpha, -1, 1))
    w = SIGMA_SPH * (1 + U_SPH * np.sin(alpha) / (np.sin(alpha) + V_SPH * np.cos(alpha)))
    denom = 2 * np.sin(alpha) * cos_g
    tan_i = np.tan(ti) * (np.sin(ti) + np.sin(tr) * np.cos(pr)) / denom
    tan_r = np.tan(tr) * (np.sin(tr) + np.sin(ti) * np.cos(pr)) / denom
    tan_g = np.abs(np.cos(ti) - cos_g) / denom
    G = (1 + w * np.abs(tan_i * tan_r) / (1 + SIGMA_R * tan_g)) / (
        (1 + w * tan_i**2) * (1 + w * tan_r**2))
    D = kr**2 * np.cos(alpha) / (1 + (kr**2 - 1) * np.cos(alpha) ** 2)
    R0 = np.exp(b * (1 - cos_g) ** a)
    return kb * D * R0 * G / np.cos(tr) + kd
