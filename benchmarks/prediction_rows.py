"""Markdown table rows of a prediction.json (crowdmpm predict --out): one row per method, after the
labels given, with windows, ADE/FDE at 1 s and 4 s and the grid velocity error at 4 s.
Usage: python3 benchmarks/prediction_rows.py PREDICTION_JSON LABEL [LABEL ...]"""
import json
import sys

j = json.load(open(sys.argv[1]))
labels = sys.argv[2:]
f = lambda v: "%.3f" % v if v is not None else "-"
for m in j["methods"]:
    h = {e["horizon_s"]: e for e in m["horizons"]}
    cells = labels + [m["method"], str(m["windows"]), f(h[1]["ade_m"]), f(h[1]["fde_m"]), f(h[4]["ade_m"]),
                      f(h[4]["fde_m"]), f(h[4]["grid_velocity_rms_m_s"])]
    print("| " + " | ".join(cells) + " |")
