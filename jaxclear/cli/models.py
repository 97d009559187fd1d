"""``jaxclear models``: list the normal contact force laws and the friction laws."""

from __future__ import annotations

import argparse

from .._storage import json_text
from ..contact.friction import FRICTION_MODELS
from ..contact.registry import describe_laws

HELP = "list the contact force laws"
DESCRIPTION = ("List every normal contact force law that --model accepts, with its parameters (defaults) and "
               "reference, and the friction laws.")


def configure(p: argparse.ArgumentParser):
    """Add ``--json``; returns the command's ``run(args) -> exit code``."""
    p.add_argument("--json", action="store_true", help="print JSON instead of text (default: text)")
    return run


def run(args) -> int:
    """Print the laws of :func:`jaxclear.contact.registry.describe_laws` as text or JSON."""
    laws = describe_laws()
    if args.json:
        print(json_text({"laws": laws, "friction": list(FRICTION_MODELS)}, sort_keys=False))
        return 0
    for law in laws:
        print(f"{law['name']}")
        print(f"    {law['formula']}")
        print(f"    reference: {law['reference']}")
        params = ", ".join(f"{k}={v}" for k, v in law["parameters"].items())
        print(f"    parameters: {params}")
        print(f"    --stiffness sets: {law['stiffness_parameter']}")
    print("friction laws (per joint): " + ", ".join(FRICTION_MODELS)
          + " (ambrosio: Ambrosio 2003 modified Coulomb; smooth: mu F_N tanh(v_T / v_s); dahl, lugre: bristle laws "
          "whose deflection the joint carries in its state)")
    return 0
