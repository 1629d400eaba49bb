"""The values Yu et al. (2026), Minerals 16, 490, publish, for side-by-side comparison.

Units are the paper's. Where the paper contradicts itself the table value is used and the
other noted (``NOTES``).
"""

REFERENCE = ("Yu, C.; Zhang, C.; Han, T.; Cao, X.; Zhao, Y.; Pan, Y. Macro-Meso-Parameter "
             "Calibration of Green Sandstone via XGBoost Screening and Stepwise Regression "
             "with Application to Impact-Fragmentation Analysis. Minerals 2026, 16, 490.")

#: Table 3: XGBoost importance (%) of each meso-parameter per response
TABLE3 = {
    "rmin_mm": {"ucs_MPa": 2.6493, "E_GPa": 0.7606, "nu": 3.0325},
    "porosity": {"ucs_MPa": 10.1454, "E_GPa": 6.8522, "nu": 6.3110},
    "pb_emod_GPa": {"ucs_MPa": 2.4741, "E_GPa": 75.2769, "nu": 0.7267},
    "pb_kratio": {"ucs_MPa": 10.4544, "E_GPa": 7.3206, "nu": 81.4671},
    "pb_ten_MPa": {"ucs_MPa": 31.7032, "E_GPa": 1.2337, "nu": 2.0245},
    "pb_coh_MPa": {"ucs_MPa": 38.0176, "E_GPa": 1.9475, "nu": 0.7543},
    "pb_fa_deg": {"ucs_MPa": 2.1244, "E_GPa": 0.8304, "nu": 2.6451},
    "fric": {"ucs_MPa": 2.4315, "E_GPa": 5.7779, "nu": 3.0389},
}

#: adjusted R^2 per response and stage (main effects, + quadratic, + interactions)
ADJ_R2 = {
    "ucs_MPa": {"main": 0.716, "quadratic": 0.726, "interaction": 0.913},
    "E_GPa": {"main": 0.822, "quadratic": 0.822},
    "nu": {"main": 0.856, "quadratic": 0.952},
}

#: the paper's equations (text form)
EQUATIONS = {
    "main": {
        "ucs_MPa": "σc = 2.20 τcp + 1.51 σcp − 428.14 n − 11.53 kp* + 115.54",
        "E_GPa": "E = 1.29 Ecp + 0.20",
        "nu": "ν = 0.044 kp* + 0.089",
    },
    "quadratic": {
        "ucs_MPa": "σc = 2.20 τcp + 1.51 σcp − 428.14 n − 2.19 kp*² + 91.83",
        "E_GPa": "E = 1.29 Ecp + 0.20",
        "nu": "ν = 0.118 kp* − 0.013 kp*² + 0.002",
    },
}

#: section 2.1 / Table 5: the lab specimens B1-B3
LAB = {
    "B1": {"ucs_MPa": 60.133, "E_GPa": 13.716, "nu": 0.255, "u_pre_MJm3": 0.168},
    "B2": {"ucs_MPa": 64.772, "E_GPa": 13.536, "nu": 0.249, "u_pre_MJm3": 0.200},
    "B3": {"ucs_MPa": 62.111, "E_GPa": 14.066, "nu": 0.267, "u_pre_MJm3": 0.169},
}

#: section 4.2: calibrated meso-parameters per specimen (n = 0.34, Rmin = 0.8 mm, a = 1.4)
CALIBRATED = {
    "B1": {"pb_emod_GPa": 10.396, "pb_kratio": 3.467, "pb_ten_MPa": 27.670, "pb_coh_MPa": 19.689},
    "B2": {"pb_emod_GPa": 10.312, "pb_kratio": 3.510, "pb_ten_MPa": 30.900, "pb_coh_MPa": 21.220},
    "B3": {"pb_emod_GPa": 10.676, "pb_kratio": 3.456, "pb_ten_MPa": 27.890, "pb_coh_MPa": 21.550},
}

#: section 4.2: what every calibrated card fixes (porosity n and Rmin)
FIXED = {"rmin_mm": 0.8, "porosity": 0.34}
#: what the paper does not state (NOTES): phi_p and mu, bpmcal's choice, the midpoints of
#: their Table 2 ranges (15-55 deg, 0.15-0.55)
UNSTATED = {"pb_fa_deg": 35.0, "fric": 0.35}


def card(spec: str = "B1") -> dict:
    """The paper's calibrated card of lab specimen ``spec`` (B1-B3; Table 5 re-runs it as
    A1-A3): all eight parameters, section 4.2's four with ``FIXED`` and ``UNSTATED``, in
    the paper's units (a new dict)."""
    return {**FIXED, **CALIBRATED[spec], **UNSTATED}


#: the paper's cards A1-A3 (lab specimens B1-B3): the one definition the tests, the
#: benchmarks and the docs' examples run
CARDS = {f"A{i}": card(f"B{i}") for i in (1, 2, 3)}
#: the card of B1, the specimen most tests and benchmarks build
A1 = CARDS["A1"]

#: Table 5: PFC3D re-runs A1-A3 of the calibrated sets, and their errors (%)
VERIFIED = {
    "B1": {"ucs_MPa": 60.187, "E_GPa": 13.643, "nu": 0.257,
           "err_pct": {"ucs_MPa": 0.090, "E_GPa": 0.530, "nu": 0.700}},
    "B2": {"ucs_MPa": 65.031, "E_GPa": 13.476, "nu": 0.258,
           "err_pct": {"ucs_MPa": 0.400, "E_GPa": 0.440, "nu": 3.614}},
    "B3": {"ucs_MPa": 64.044, "E_GPa": 14.044, "nu": 0.257,
           "err_pct": {"ucs_MPa": 3.110, "E_GPa": 0.160, "nu": 3.745}},
}

#: Table 6: pre-peak energy density, simulated (A) vs lab (B), MJ/m^3
PREPEAK = {
    "B1": {"sim": 0.138, "lab": 0.168, "err_pct": 17.86},
    "B2": {"sim": 0.167, "lab": 0.200, "err_pct": 15.60},
    "B3": {"sim": 0.156, "lab": 0.169, "err_pct": 7.69},
}

#: section 4.2: chosen bond-strength ratio
RATIO = 1.4

#: section 4.4: drop-hammer impact at 6 m/s on the 50 x 100 mm specimen
IMPACT = {"velocity": 6.0, "W_in_J": 78.9, "eta_f": 0.237}

NOTES = [
    "Section 2.1 gives E = 13.688 GPa for B1; Table 5 gives 13.716 GPa (the value its 0.530 % "
    "error refers to). bpmcal uses 13.716.",
    "Table 6 lists a 15.60 % error for specimen 2; the text says 16.50 %. (0.200-0.167)/0.200 "
    "= 16.5 %.",
    "The paper does not state phi_p, mu_p, the hammer mass, the dashpot damping, the loading "
    "rate or its genesis procedure; bpmcal's choices are listed in the report.",
]
