#!/usr/bin/env python3
"""Fits the start of render/bsdfs/microfacet.h's Beckmann visible-slope inversion.

At unit roughness and incidence theta the slope x along the view plane has the CDF
C(x) ~ 1 + erf(x) + tan(theta) / sqrt(pi) exp(-x^2) on x < cot(theta). In b = erf(x) the
exact inverse b(u) is close to hi - (1 + hi) (1 - u)^p(theta), hi = erf(cot theta) (the form
of Jakob 2014). This script finds p by least squares over u for 60 angles and fits a cubic in
theta to it; the printed coefficients (highest power first) are the ones in microfacet.h.
Needs numpy and scipy.
"""
import numpy as np
from scipy.optimize import brentq, minimize_scalar
from scipy.special import erf, erfinv

thetas = np.linspace(0.01, np.pi / 2 - 0.01, 60)
us = np.linspace(0.01, 0.99, 99)
ps = []
for th in thetas:
    tan = np.tan(th)
    hi = erf(1 / tan)
    k = tan / np.sqrt(np.pi)
    total = 1 + hi + k * np.exp(-1 / tan ** 2)
    cdf = lambda b, u: 1 + b + k * np.exp(-erfinv(b) ** 2) - u * total
    exact = np.array([brentq(cdf, -1 + 1e-15, hi, args=(u,)) for u in us])
    err = lambda p: np.sum((hi - (1 + hi) * (1 - us) ** p - exact) ** 2)
    ps.append(minimize_scalar(err, bounds=(0.1, 3), method='bounded').x)
ps = np.array(ps)
coef = np.polyfit(thetas, ps, 3)
print('p(theta) coefficients, theta^3 .. theta^0:', list(coef))
print('largest misfit of p:', np.max(np.abs(np.polyval(coef, thetas) - ps)))
