"""The cases of the reliability corpus: damaged recordings, stands, maps, options and output targets, built from one
simulated impact (see :mod:`reliability_corpus` for how a run is judged)."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import h5py
import numpy as np
import scipy.io

from impactometer.cli import main
from impactometer.errors import ImpactometerError
from impactometer.io import read_recording, write_recording
from impactometer.model import simulate
from impactometer.recording import Recording
from impactometer.rig import Scenario
from impactometer.sensors import apply_sensors, record
from reliability_corpus import FS, Case, write_csv, write_h5, write_tdms


class Corpus:
    """The cases, built in ``folder`` from one simulated impact (30 kg at 1.98 m/s, 50 kHz, 1 % noise)."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        scenario = Scenario.from_height(mass=30.0, height=0.2, pressure_gauge=200e3)
        self.rec = record(scenario, sample_rate=FS, duration=0.1, noise=0.01, seed=1, pre_trigger=0.05)
        self.truth = (self.rec.truth("mass_kg"), self.rec.truth("velocity_m_s"))
        self.f, self.a = self.rec.contact_force, self.rec.piston_acceleration
        self.base = write_recording(self.rec, self.folder / "base.h5", overwrite=True)
        self.map = self.folder / "map.h5"
        if not self.map.exists():
            main(["map", "build", "--out", str(self.map), "--grid", "8x8"])

    def path(self, name: str) -> Path:
        return self.folder / name

    def recording(self, name: str, force, acceleration, **metadata) -> Path:
        rec = Recording(sample_rate=FS, channels={"contact_force": force, "piston_acceleration": acceleration},
                        start_time=self.rec.start_time, metadata={**self.rec.metadata, **metadata})
        return write_recording(rec, self.path(name), overwrite=True)

    def cases(self) -> list[Case]:
        out: list[Case] = []
        for build in (self.stream_vs_identify, self.another_stand, self.duplicated, self.outputs, self.settings,
                      self.rates, self.maps, self.truth_metadata, self.implausible, self.smaller, self.stands,
                      self.csv_structure, self.contents, self.options, self.late_trigger, self.clipped_acceleration,
                      self.slow_errors, self.map_pressure, self.csv_decimals, self.high_rates, self.special_targets,
                      self.pointing, self.unit_slips, self.other_machines, self.clipped_in_flight, self.megahertz,
                      self.bare_command):
            out += build()
        return out

    # 1 --------------------------------------------------------------------------------------------------------
    def stream_vs_identify(self) -> list[Case]:
        t, f, a = self.rec.time, self.f, self.a
        square = np.sign(np.sin(2 * np.pi * 60 * t))
        rng = np.random.default_rng(2)
        damaged = {"clipped force": (np.minimum(f, 0.3 * f.max()), a), "reversed acceleration": (f, -a),
                   "square-wave acceleration": (f, 50.0 * square), "zero acceleration": (f, 0 * a),
                   "square-wave force": (3e3 * (square > 0), a),
                   "force spike": (f + 1e6 * (np.arange(f.size) == 4000), a),
                   "force offset": (f + 5e3, a), "intact": (f, a), "acceleration ×1000": (f, 1e3 * a),
                   "force and acceleration swapped": (a, f),
                   "noise only": (rng.normal(0, 20, f.size), rng.normal(0, 5, a.size))}
        out = []
        for i, (label, (force, acceleration)) in enumerate(damaged.items()):
            path = self.recording(f"stream{i}.h5", force, acceleration)
            expect = "answer" if label in ("intact", "force offset") else "either"
            out.append(Case("stream vs identify", f"identify: {label}", ["identify", str(path), "--json"], expect,
                            self.truth))
            out.append(Case("stream vs identify", f"stream: {label}", ["stream", str(path), "--json"], expect,
                            self.truth, same_as=f"identify: {label}"))
        return out

    # 2 --------------------------------------------------------------------------------------------------------
    def another_stand(self) -> list[Case]:
        stands = {"heavier piston": "[cylinder]\npiston_mass = 8.0\n", "more friction": "[friction]\nforce = 80.0\n",
                  "softer contact": "[contact]\nstiffness = 1e6\n", "same stand, other name": 'name = "lab-B"\n'}
        out = []
        for i, (label, toml) in enumerate(stands.items()):
            stand = self.path(f"stand{i}.toml")
            stand.write_text(toml)
            path = self.path(f"stand{i}.h5")
            main(["record", "--out", str(path), "--rig", str(stand), "--noise", "1%", "--seed", "1", "--force"])
            out.append(Case("map of another stand", label, ["identify", str(path), "--method", "response-map",
                                                              "--map", str(self.map), "--json"],
                            "answer" if "same stand" in label else "refuse", self.truth))
        return out

    # 3 --------------------------------------------------------------------------------------------------------
    def duplicated(self) -> list[Case]:
        ch = {"contact_force": self.f, "piston_acceleration": self.a}
        files = {
            "HDF5 fs and sample_rate": write_h5(self.path("dup0.h5"), ch, {"fs": 50000, "sample_rate": 10000}),
            "HDF5 root and group rate": write_h5(self.path("dup1.h5"), ch, {"fs": 50000}, group="g",
                                                 group_attrs={"fs": 10000}),
            "HDF5 dt and fs": write_h5(self.path("dup2.h5"), ch, {"fs": 50000, "dt": 1e-4}),
            "HDF5 start_time and t0": write_h5(self.path("dup3.h5"), ch, {"fs": 5e4, "start_time": -0.05, "t0": 0.0}),
            "HDF5 truth in attribute and JSON": write_h5(self.path("dup4.h5"), ch, {
                "fs": 5e4, "mass_kg": 3.0, "metadata": json.dumps({"mass_kg": 30.0})}),
            "TDMS channel and group rate": write_tdms(self.path("dup5.tdms"), ch, channel_props={"wf_increment": 2e-5},
                                                      group_props={"sample_rate": 1e4}),
            "CSV time column and sidecar rate": write_csv(self.path("dup6.csv"), {
                "time [s]": self.rec.time, "force [N]": self.f, "acc [m/s^2]": self.a}, sidecar={"sample_rate": 1e4}),
        }
        variables = {"force": self.f, "acc": self.a, "fs": 5e4, "dt": 1e-4}
        scipy.io.savemat(self.path("dup7.mat"), variables)
        files["MAT fs and dt"] = self.path("dup7.mat")
        return [Case("duplicated statements", f"{command}: {label}", [command, str(path)])
                for label, path in files.items() for command in ("identify", "inspect")]

    # 5 --------------------------------------------------------------------------------------------------------
    def outputs(self) -> list[Case]:
        folder = self.path("targets")
        folder.mkdir(exist_ok=True)
        existing = folder / "kept.png"
        if not existing.exists():
            existing.write_bytes(b"a figure worth keeping")
        kept_csv = folder / "kept.csv"
        if not kept_csv.exists():
            kept_csv.write_text("time,force\n0,1\n")
        plain_file = folder / "a-file"
        plain_file.write_text("not a folder")
        base = str(self.base)
        cases = {
            "figure extension .xyz": ["identify", base, "--plot", str(folder / "fig.xyz")],
            "figure without extension": ["inspect", base, "--plot", str(folder / "fig")],
            "figure target is a folder, --force": ["identify", base, "--plot", str(folder), "--force"],
            "recording target is a folder, --force": ["record", "--out", str(folder), "--force"],
            "recording with unknown extension": ["record", "--out", str(folder / "x.xlsx")],
            "existing figure without --force": ["inspect", base, "--plot", str(existing)],
            "existing recording without --force": ["record", "--out", str(kept_csv)],
            "folder that does not exist": ["simulate", "--out", str(folder / "none" / "x.h5")],
            "study --out names a file": ["study", "peak-force", "--out", str(plain_file), "--grid", "2"],
            "demo --out names a file": ["demo", "--out", str(plain_file), "--no-absorb"],
            "map --out is a folder": ["map", "build", "--out", str(folder), "--grid", "3", "--force"],
            "identify --plot with a response map": ["identify", base, "--method", "response-map", "--map",
                                                    str(self.map), "--plot", str(folder / "f.png")],
        }
        return [Case("output targets", label, argv, protect=(existing, kept_csv, plain_file))
                for label, argv in cases.items()]

    # 6 --------------------------------------------------------------------------------------------------------
    def settings(self) -> list[Case]:
        out_dir = str(self.path("study"))
        sets = ["noise.levels=[]", "noise.levels=[-1]", "noise.levels=[NaN]", 'noise.levels="abc"', "noise.levels=abc",
                "peak-force.nope=1", "nope.levels=1", "noise=1", "noise.levels=[1e999]", "sampling.rates=[1e9]",
                "map-size.sizes=[2.5]", "map-size.features=[\"fft\"]", "absorption.identification=\"x\"",
                "noise.levels=" + "[" * 3000, "cases.velocities=[30]", "noise.chunk_size=0", "window.windows=[-1]"]
        cases = [Case("study settings", f"--set {s[:40]}", ["study", "noise", "--out", out_dir, "--set", s])
                 for s in sets]
        for option, value in (("--grid", "1000"), ("--grid", "1"), ("--grid", "-3"), ("--seeds", "0"),
                              ("--seeds", "100000"), ("--seed", "-1"), ("--noise", "200%"), ("--sample-rate", "1GHz"),
                              ("--duration", "1e9s"), ("--pre-trigger", "-1ms"), ("--workers", "0")):
            cases.append(Case("study settings", f"{option} {value}", ["study", "noise", "--out", out_dir, option,
                                                                        value]))
        return cases

    # 7 --------------------------------------------------------------------------------------------------------
    def rates(self) -> list[Case]:
        bare = write_csv(self.path("bare.csv"), {"force [N]": self.f, "acc [m/s^2]": self.a})
        out = [Case("sample rates", f"--sample-rate {rate}", ["identify", str(bare), "--sample-rate", rate, "--json"],
                    "either", self.truth)
               for rate in ("1mHz", "1e308", "1e20", "1THz", "0", "-1", "nan", "fast", "1GHz", "1e-300", "1mhz",
                            "50kHz")]
        # a rate within range but not the file's: the answer is right for the data as stated (time runs 20 times
        # faster, V0 comes out 20 times smaller); nothing in the signals tells
        out.append(Case("sample rates", "--sample-rate 1MHz", ["identify", str(bare), "--sample-rate", "1MHz",
                                                               "--json"], "answer"))
        ch = {"contact_force": self.f, "piston_acceleration": self.a}
        files = {"HDF5 fs = 1e300": write_h5(self.path("rate0.h5"), ch, {"fs": 1e300}),
                 "HDF5 fs = 1e19": write_h5(self.path("rate1.h5"), ch, {"fs": 1e19}),
                 "HDF5 fs = 1 GHz": write_h5(self.path("rate2.h5"), ch, {"fs": 1e9}),
                 "HDF5 fs = '50k'": write_h5(self.path("rate3.h5"), ch, {"fs": "50k"}),
                 "HDF5 fs = NaN": write_h5(self.path("rate4.h5"), ch, {"fs": np.nan}),
                 "TDMS wf_increment = 1e-300": write_tdms(self.path("rate5.tdms"), ch,
                                                          channel_props={"wf_increment": 1e-300}),
                 "CSV time spacing 1e-300": write_csv(self.path("rate6.csv"), {
                     "time [s]": np.arange(self.f.size) * 1e-300, "force [N]": self.f, "acc [m/s^2]": self.a})}
        scipy.io.savemat(self.path("rate7.mat"), {"force": self.f, "acc": self.a, "fs": 1e300})
        files["MAT fs = 1e300"] = self.path("rate7.mat")
        out += [Case("sample rates", label, ["identify", str(path), "--json"], "either", self.truth)
                for label, path in files.items()]
        out.append(Case("sample rates", "stream, HDF5 fs = 1e19", ["stream", str(files["HDF5 fs = 1e19"])]))
        out.append(Case("sample rates", "simulate --sample-rate 1THz", ["simulate", "--sample-rate", "1THz"]))
        out.append(Case("sample rates", "record --sample-rate 1mHz", ["record", "--out", str(self.path("r.csv")),
                                                                      "--sample-rate", "1mHz", "--force"]))
        return out

    # 8 --------------------------------------------------------------------------------------------------------
    def maps(self) -> list[Case]:
        edits = {"schema_version 'abc'": ("schema_version", "abc"), "schema_version NaN": ("schema_version", np.nan),
                 "schema_version array": ("schema_version", np.arange(3)), "schema_version 2": ("schema_version", 2),
                 "sample_rate '50k'": ("sample_rate", "50k"), "sample_rate array": ("sample_rate", np.ones(3)),
                 "sample_rate 1e300": ("sample_rate", 1e300), "sample_rate 25 kHz": ("sample_rate", 25e3),
                 "feature_set 'fft'": ("feature_set", "fft"), "rig JSON too deep": ("rig", "[" * 100000),
                 "rig of another stand": ("rig", None),
                 "feature_params window -1": ("feature_params", '{"window": -1}'),
                 "provenance not JSON": ("provenance", "{"), "values doubled": ("values", None)}
        out = []
        for i, (label, (key, value)) in enumerate(edits.items()):
            path = self.path(f"map{i}.h5")
            path.write_bytes(self.map.read_bytes())
            with h5py.File(path, "r+") as h5:
                if key == "values":
                    h5["values"][...] = 2.0 * h5["values"][()]
                elif key == "rig":
                    stand = json.loads(h5.attrs["rig"])
                    stand["cylinder"]["piston_mass"] = 8.0
                    h5.attrs["rig"] = json.dumps(stand) if value is None else value
                else:
                    h5.attrs[key] = value
            out += self._map_commands(label, path)
        raw = self.map.read_bytes()
        for k, position in enumerate(range(64, len(raw), max(1, len(raw) // 12))):
            path = self.path(f"flip{k}.h5")
            flipped = bytearray(raw)
            flipped[position] ^= 0xFF
            path.write_bytes(bytes(flipped))
            out += self._map_commands(f"byte {position} flipped", path, expect="either")
        cut = self.path("cut.h5")
        cut.write_bytes(raw[:len(raw) // 2])
        out += self._map_commands("truncated to half", cut)
        return out

    def _map_commands(self, label: str, path: Path, expect: str = "refuse") -> list[Case]:
        return [Case("map files", f"map info: {label}", ["map", "info", str(path)], expect),
                Case("map files", f"identify: {label}", ["identify", str(self.base), "--method", "response-map",
                                                         "--map", str(path), "--json"], expect, self.truth)]

    # 9 --------------------------------------------------------------------------------------------------------
    def truth_metadata(self) -> list[Case]:
        values = {"text": "heavy", "NaN text": "NaN", "array": [1, 2], "negative": -5.0, "huge": 1e300, "boolean": True,
                  "object": {"kg": 3}}
        out = []
        for i, (label, value) in enumerate(values.items()):
            path = write_csv(self.path(f"truth{i}.csv"), {"time [s]": self.rec.time, "force [N]": self.f,
                                                          "acc [m/s^2]": self.a}, sidecar={"mass_kg": value})
            out.append(Case("truth metadata", f"sidecar mass_kg {label}", ["inspect", str(path)]))
        ch = {"contact_force": self.f, "piston_acceleration": self.a}
        out.append(Case("truth metadata", "HDF5 attribute mass_kg 'heavy'", ["inspect", str(write_h5(
            self.path("truth_a.h5"), ch, {"fs": 5e4, "mass_kg": "heavy"}))]))
        out.append(Case("truth metadata", "HDF5 JSON velocity_m_s 'fast'", ["inspect", str(write_h5(
            self.path("truth_b.h5"), ch, {"fs": 5e4, "metadata": json.dumps({"velocity_m_s": "fast"})}))]))
        scipy.io.savemat(self.path("truth_c.mat"), {"force": self.f, "acc": self.a, "fs": 5e4, "mass_kg": "heavy"})
        out.append(Case("truth metadata", "MAT variable mass_kg 'heavy'", ["inspect", str(self.path("truth_c.mat"))]))
        out.append(Case("truth metadata", "TDMS property pressure_gauge_Pa 'high'", ["inspect", str(write_tdms(
            self.path("truth_d.tdms"), ch, channel_props={"wf_increment": 2e-5},
            root_props={"pressure_gauge_Pa": "high"}))]))
        out.append(Case("truth metadata", "sidecar mass_kg '30 kg' (a unit)", ["inspect", str(write_csv(
            self.path("truth_e.csv"), {"time [s]": self.rec.time, "force [N]": self.f}, sidecar={"mass_kg": "30 kg"}))],
            "answer"))
        return out

    # 10 -------------------------------------------------------------------------------------------------------
    def implausible(self) -> list[Case]:
        f, a = self.f, self.a
        # an acceleration read ÷9.81 is recognised through the onset equations of a stand that rebounds several
        # times; on the pad stand, whose answer rests on stage B, it is not (test_reliability: the known miss)
        stiff = record(Scenario.from_height(mass=30.0, height=0.2, pressure_gauge=200e3), "drop-stand-stiff",
                       sample_rate=FS, duration=0.1, noise=0.01, seed=1, pre_trigger=0.05)
        signals = {"acceleration ÷1000": (f, a / 1e3),
                   "acceleration in g read as m/s² (stiff stand)": (stiff.contact_force,
                                                                    stiff.piston_acceleration / 9.80665),
                   "force in kN read as N": (f / 1e3, a), "force in N read as kN": (f * 1e3, a),
                   "acceleration ×9.81": (f, a * 9.80665)}
        out = [Case("implausible answers", label, ["identify", str(self.recording(f"unit{i}.h5", force, acc)),
                                                   "--json"], "either", self.truth)
               for i, (label, (force, acc)) in enumerate(signals.items())]
        out.append(Case("implausible answers", "channels named the other way round",
                        ["identify", str(self.base), "--force-channel", "piston_acceleration",
                         "--acceleration-channel", "contact_force", "--json"], "either", self.truth))
        scipy.io.savemat(self.path("logical.mat"), {"force": f > 0.3 * f.max(), "acc": a, "fs": 5e4})
        out.append(Case("implausible answers", "MAT logical force channel",
                        ["identify", str(self.path("logical.mat")), "--json"], "either", self.truth))
        calibration = self.path("calibration")
        calibration.mkdir(exist_ok=True)
        rows = ["file,mass_kg,velocity_m_s"]
        for k, (mass, height) in enumerate((m, h) for m in (10.0, 30.0, 50.0) for h in (0.1, 0.2, 0.4)):
            name = f"c{k}.h5"
            rec = record(Scenario.from_height(mass=mass, height=height, pressure_gauge=200e3), sample_rate=FS,
                         duration=0.05, noise=0.005, seed=k)
            write_recording(rec, calibration / name, overwrite=True)
            rows.append(f"{name},{rec.truth('velocity_m_s'):.4f},{mass}")  # the columns swapped
        (calibration / "manifest.csv").write_text("\n".join(rows) + "\n")
        out.append(Case("implausible answers", "manifest with mass and velocity swapped",
                        ["map", "build", "--from-recordings", str(calibration), "--grid", "6",
                         "--out", str(self.path("cal.h5")), "--force"]))
        return out

    # 11 -------------------------------------------------------------------------------------------------------
    def smaller(self) -> list[Case]:
        deep = self.path("deep.toml")
        deep.write_text("x = " + "[" * 3000 + "]" * 3000 + "\n")
        stiff = self.path("stiff.toml")
        stiff.write_text("[contact]\nstiffness = 1e300\n")
        bore = self.path("bore.toml")
        bore.write_text("[cylinder]\nbore = 100.0\n")
        return [Case("smaller breaks", "record --seed -1", ["record", "--out", str(self.path("s.csv")), "--seed",
                                                            "-1"]),
                Case("smaller breaks", "stand TOML nested 3000 deep", ["simulate", "--rig", str(deep)]),
                Case("smaller breaks", "reference integrator, mass 1e-9 kg", ["simulate", "--integrator", "reference",
                                                                             "--mass", "1e-9kg"]),
                Case("smaller breaks", "reference integrator, stiffness 1e300", ["simulate", "--integrator",
                                                                                "reference", "--rig", str(stiff)],
                     slow=True),
                Case("smaller breaks", "map build --grid 3000x3000", ["map", "build", "--out", str(self.path("big.h5")),
                                                                      "--grid", "3000x3000"]),
                Case("smaller breaks", "study --scheduler inproc://x", ["study", "peak-force", "--out",
                                                                        str(self.path("dask")), "--scheduler",
                                                                        "inproc://x"]),
                Case("smaller breaks", "stand TOML bore = 100.0", ["simulate", "--rig", str(bore)]),
                Case("smaller breaks", "stream --chunk 0", ["stream", str(self.base), "--chunk", "0"])]

    # own: stand files, CSV structure, command options -----------------------------------------------------------
    def stands(self) -> list[Case]:
        texts = {"unknown key": "[cylinder]\nwidth = 3\n", "text value": '[cylinder]\nbore = "wide"\n',
                 "NaN": "[cylinder]\nbore = nan\n", "negative": "[cylinder]\nstroke = -0.1\n",
                 "rod wider than bore": "[cylinder]\nrod_diameter = 0.1\n", "law 'glue'": '[contact]\nlaw = "glue"\n',
                 "not TOML": "[[[", "binary": "\x00\x01\x02", "section not a table": "cylinder = 3\n",
                 "gamma 7": "[gas]\ngamma = 7.0\n", "infinite stiffness": "[stops]\nstiffness = inf\n", "empty": ""}
        out = []
        for i, (label, text) in enumerate(texts.items()):
            path = self.path(f"bad{i}.toml")
            path.write_text(text)
            out.append(Case("stand files", label, ["simulate", "--rig", str(path)]))
        return out

    def pointing(self) -> list[Case]:
        """Refusals that name the way out: the option given in vain, the option's own text, the file's field."""
        contact = int(np.flatnonzero(self.rec.time >= 0.0)[0])
        short = self.recording("short.h5", self.f[:contact + int(0.005 * FS)], self.a[:contact + int(0.005 * FS)])
        missing = self.path("never-written.h5")
        empty, rubber = self.path("empty.toml"), self.path("rubber.toml")
        empty.write_text("")
        rubber.write_text('[contact]\nlaw = "rubber"\n')
        model = ["--method", "model"]
        return [Case("pointing", "--flip-force on a force of the right sign",
                     ["identify", str(self.base), "--flip-force"], reason="leave --flip-force out"),
                Case("pointing", "stream --cadence 0ms, before reading", ["stream", str(missing), *model, "--cadence",
                                                                          "0ms"], reason="--cadence 0ms: must be > 0"),
                Case("pointing", "stream --first 100ms, before reading", ["stream", str(missing), *model, "--first",
                                                                          "100ms"], reason="--first 100ms: must be <="),
                Case("pointing", "stream --method model on 5 ms of contact", ["stream", str(short), *model],
                     reason="needs at least 10 ms"),
                Case("pointing", "empty stand file", ["simulate", "--rig", str(empty)], reason="holds no stand"),
                Case("pointing", "stand file with law 'rubber'", ["identify", str(self.base), *model, "--rig",
                                                                  str(rubber)],
                     reason=f"--rig {rubber}: contact.law must be one of")]

    def csv_structure(self) -> list[Case]:
        rng = np.random.default_rng(5)
        texts = {"empty": "", "header only": "time [s],force [N]\n", "random bytes": rng.bytes(2000),
                 "NUL bytes": b"time,force\n0,1\x00\n", "ragged rows": "time,force,acc\n0,1,2\n1e-5,2\n",
                 "text cell": "time,force,acc\n0,1,2\n1e-5,two,3\n", "numeric header": "1,2\n3,4\n",
                 "duplicate header": "force,force\n1,2\n", "one row": "time,force,acc\n0,1,2\n"}
        out = []
        for i, (label, text) in enumerate(texts.items()):
            path = self.path(f"struct{i}.csv")
            path.write_bytes(text if isinstance(text, bytes) else text.encode())
            out.append(Case("CSV structure", label, ["identify", str(path)]))
        semi = write_csv(self.path("semicolon.csv"), {"Zeit [s]": self.rec.time, "Force [kN]": self.f / 1e3,
                                                      "Acc [m/s^2]": self.a}, separator=";", fmt="%.9f")
        semi.write_text(semi.read_text().replace(".", ","))
        out.append(Case("CSV structure", "semicolons and decimal commas", ["identify", str(semi), "--json"], "answer",
                        self.truth))
        return out

    def contents(self) -> list[Case]:
        f, a, t = self.f, self.a, self.rec.time
        nan = f.copy()
        nan[3000] = np.nan
        files = {
            "channels of different lengths": (write_h5(self.path("len.h5"), {"force": f, "acc": a[:-100]},
                                                       {"fs": 5e4}), "refuse"),
            "force of 1e300 N": (write_h5(self.path("huge.h5"), {"force": f * 1e296, "acc": a}, {"fs": 5e4}), "either"),
            "NaN in the force": (write_h5(self.path("nan.h5"), {"force": nan, "acc": a}, {"fs": 5e4}), "refuse"),
            "int16 ADC counts": (write_h5(self.path("int16.h5"), {"force": np.round(f).astype(np.int16),
                                                                  "acc": np.round(a).astype(np.int16)},
                                          {"fs": 5e4, "start_time": -0.05}), "either"),
            "float32 channels": (write_h5(self.path("f32.h5"), {"force": f.astype(np.float32),
                                                                "acc": a.astype(np.float32)},
                                          {"fs": 5e4, "start_time": -0.05}), "answer"),
            "start time 1.7e9 s (a clock)": (write_h5(self.path("clock.h5"), {"force": f, "acc": a},
                                                      {"fs": 5e4, "start_time": 1.7e9}), "answer"),
            "time column in ms": (write_csv(self.path("ms.csv"), {"t [ms]": t * 1e3, "force [N]": f,
                                                                  "acc [m/s^2]": a}), "answer"),
            "8 samples": (write_h5(self.path("short.h5"), {"force": f[2500:2508], "acc": a[2500:2508]},
                                   {"fs": 5e4}), "refuse"),
            "constant force": (write_h5(self.path("flat.h5"), {"force": 0 * f + 3.0, "acc": a}, {"fs": 5e4}),
                               "refuse"),
            "force in tension (sign flipped)": (write_h5(self.path("tension.h5"), {"force": -f, "acc": a}, {"fs": 5e4}),
                                                "refuse"),
            "no acceleration channel": (write_h5(self.path("noacc.h5"), {"force": f, "other": a}, {"fs": 5e4}),
                                        "refuse"),
            "force unit 'furlong'": (self._unit_file("furlong"), "refuse"),
        }
        out = [Case("recording content", label, ["identify", str(path), "--json"], expect,
                    self.truth if expect != "refuse" else None) for label, (path, expect) in files.items()]
        out += [Case("recording content", f"inspect: {label}", ["inspect", str(path)], "either")
                for label, (path, _) in files.items()]
        return out

    def _unit_file(self, unit: str) -> Path:
        path = write_h5(self.path(f"unit-{unit}.h5"), {"force": self.f, "acc": self.a}, {"fs": 5e4})
        with h5py.File(path, "r+") as h5:
            h5["force"].attrs["unit"] = unit
        return path

    def options(self) -> list[Case]:
        base = str(self.base)
        cases = {"--mass heavy": ["simulate", "--mass", "heavy"],
                 "--velocity 1e308": ["simulate", "--velocity", "1e308"],
                 "--height -1m": ["simulate", "--height", "-1m"], "--duration 1e9s": ["simulate", "--duration", "1e9s"],
                 "--velocity 30m/s": ["simulate", "--velocity", "30m/s"], "--cfc 7": ["identify", base, "--cfc", "7"],
                 "--variant x": ["identify", base, "--variant", "x"], "--search x": ["identify", base, "--method",
                                                                                    "response-map", "--map",
                                                                                    str(self.map), "--search", "x"],
                 "--group on CSV": ["identify", str(self.path("bare.csv")), "--group", "g"],
                 "--noise 0.9 (a fraction)": ["record", "--out", str(self.path("n.csv")), "--noise", "0.9"],
                 "--adc-bits 64": ["record", "--out", str(self.path("n.csv")), "--adc-bits", "64", "--force"],
                 "--extra nope": ["record", "--out", str(self.path("n.csv")), "--extra", "nope", "--force"]}
        return [Case("command options", label, argv) for label, argv in cases.items()]

    # records from outside our own corpus ---------------------------------------------------------------------
    def _pair(self, category: str, label: str, path: Path, expect: str, truth=None, **judged) -> list[Case]:
        """The case for identify and the same for stream, which must agree with it."""
        return [Case(category, f"identify: {label}", ["identify", str(path), "--json"], expect, truth, **judged),
                Case(category, f"stream: {label}", ["stream", str(path), "--json", "--chunk", "1024"], expect, truth,
                     same_as=f"identify: {label}", **judged)]

    def _from(self, first: int, name: str, force=None, acceleration=None) -> Path:
        """The record from sample ``first`` on, with its time from 0 (a DAQ without pre-trigger)."""
        force = self.f if force is None else force
        acceleration = self.a if acceleration is None else acceleration
        rec = Recording(sample_rate=FS, channels={"contact_force": force[first:],
                                                  "piston_acceleration": acceleration[first:]},
                        start_time=0.0, metadata=self.rec.metadata)
        return write_recording(rec, self.path(name), overwrite=True)

    def late_trigger(self) -> list[Case]:
        """Records that begin inside the impact: V0 22.5 % low 2 ms late, without a word, before."""
        first = int(np.flatnonzero(self.rec.time >= self.rec.metadata["anti_alias_delay_s"])[0])
        out = []
        for late in (1e-3, 2e-3, 10e-3):
            path = self._from(first + int(round(late * FS)), f"late{late * 1e3:g}ms.h5")
            label = f"{late * 1e3:g} ms after first contact"
            out += self._pair("late trigger", label, path, "refuse", self.truth, reason="begins inside a contact pulse")
            out.append(Case("late trigger", f"map: {label}", ["identify", str(path), "--method", "response-map",
                                                              "--map", str(self.map), "--json"], "refuse", self.truth,
                            reason="begins inside a contact pulse"))
        out += self._pair("late trigger", "from first contact on", self._from(first - 4, "late0ms.h5"), "answer",
                          self.truth, sigmas=3.0)
        return out

    def clipped_acceleration(self) -> list[Case]:
        a = self.a
        clipped = {"at 80 % of its peak": np.minimum(a, 0.8 * a.max()),
                   "at 95 % of its peak": np.minimum(a, 0.95 * a.max()),
                   "both rails at 80 %": np.clip(a, 0.8 * a.min(), 0.8 * a.max()),
                   "its minimum at 60 %": np.maximum(a, 0.6 * a.min())}
        out = []
        for i, (label, acceleration) in enumerate(clipped.items()):
            out += self._pair("clipped acceleration", label, self.recording(f"aclip{i}.h5", self.f, acceleration),
                              "refuse", self.truth, reason="piston_acceleration is saturated")
        return out

    def slow_errors(self) -> list[Case]:
        """Drift, an offset without pre-trigger and mains hum, on the reference truth record (seed 0, 20 ms of
        pre-trigger): within 3 standard errors, or refused naming the hum."""
        truth = record(Scenario.from_height(mass=30.0, height=0.2, pressure_gauge=200e3), sample_rate=FS,
                       duration=0.1, noise=0.01, seed=0, pre_trigger=0.02)
        t, f, a = truth.time, truth.contact_force, truth.piston_acceleration
        first = int(np.flatnonzero(t >= 0.0)[0])
        expected = (30.0, truth.truth("velocity_m_s"))

        def recording(name, acceleration, start=0):
            channels = {"contact_force": f[start:], "piston_acceleration": acceleration[start:]}
            rec = Recording(sample_rate=FS, channels=channels, start_time=t[0] if start == 0 else 0.0,
                            metadata=truth.metadata)
            return write_recording(rec, self.path(name), overwrite=True)

        signals = {"drift of 1 m/s² over the record": ("drift.h5", a + np.linspace(0.0, 1.0, a.size), 0, "answer"),
                   "drift of 1 m/s² per 150 ms from first contact": ("drift2.h5", a + np.clip(t, 0.0, None) / 0.15, 0,
                                                                     "answer"),
                   "no pre-trigger, offset 0.5 m/s²": ("offset.h5", a + 0.5, first, "answer")}
        # a hum the pre-trigger shows is removed (it was refused where it correlated the pre-trigger, and put M1
        # three standard errors off at 0.2 % of the peak, where it did not)
        for frequency, level, expect in ((50.0, 0.001, "answer"), (50.0, 0.002, "answer"), (50.0, 0.003, "answer"),
                                         (60.0, 0.01, "answer"), (50.0, 0.02, "answer")):
            hum = level * np.max(np.abs(a)) * np.sin(2.0 * np.pi * frequency * t + 0.3)
            signals[f"{frequency:g} Hz hum at {level:.1%} of the peak"] = (f"hum{frequency:g}-{level:g}.h5", a + hum, 0,
                                                                             expect)
        out = []
        for label, (name, acceleration, start, expect) in signals.items():
            judged = {"sigmas": 3.0} if expect == "answer" else {"reason": "mains hum"}
            out += self._pair("slow acceleration errors", label, recording(name, acceleration, start), expect, expected,
                              **judged)
        return out

    def map_pressure(self) -> list[Case]:
        """The response map read at its own pressure when the file stated none: M1 62 % low, silently."""
        low = record(Scenario.from_height(mass=30.0, height=0.2, pressure_gauge=100e3), sample_rate=FS, duration=0.1,
                     noise=0.01, seed=1, pre_trigger=0.05)
        stated = write_recording(low, self.path("p100.h5"), overwrite=True)
        bare = write_recording(Recording(sample_rate=FS, channels=low.channels, start_time=low.start_time),
                               self.path("p100-bare.h5"), overwrite=True)
        bare200 = write_recording(Recording(sample_rate=FS, channels=self.rec.channels, start_time=self.rec.start_time),
                                  self.path("p200-bare.h5"), overwrite=True)
        command = ["--method", "response-map", "--map", str(self.map), "--json"]
        truth = (30.0, low.truth("velocity_m_s"))
        return [Case("map pressure", "no pressure stated or given", ["identify", str(bare), *command], "refuse", truth,
                     reason="the charge pressure is not known"),
                Case("map pressure", "--pressure 100kPa, a 200 kPa map", ["identify", str(bare), *command,
                                                                          "--pressure", "100kPa"], "refuse", truth,
                     reason="made for a charge pressure of 200 kPa"),
                Case("map pressure", "--pressure 200kPa, the file states 100 kPa", ["identify", str(stated), *command,
                                                                                    "--pressure", "200kPa"],
                     "refuse", truth, reason="contradicts"),
                Case("map pressure", "--pressure 200kPa, none stated", ["identify", str(bare200), *command,
                                                                        "--pressure", "200kPa"], "answer", self.truth),
                Case("map pressure", "--pressure 200kPa as stated", ["identify", str(self.base), *command,
                                                                     "--pressure", "200kPa"], "answer", self.truth)]

    def csv_decimals(self) -> list[Case]:
        """Decimal commas whose first data row holds none (0;0;0) were refused."""
        time = self.rec.time - self.rec.time[0]
        f, a = self.f.copy(), self.a.copy()
        f[0] = a[0] = 0.0
        out = []
        for separator, name in ((";", "decimal0.csv"), ("\t", "decimal0.tsv")):
            path = write_csv(self.path(name), {"time [s]": time, "force [N]": f, "acc [m/s^2]": a},
                             separator=separator, fmt="%.9g")
            path.write_text(path.read_text().replace(".", ","))
            out.append(Case("CSV decimal style", f"first row 0{separator}0{separator}0".replace("\t", "⇥"),
                            ["identify", str(path), "--json"], "answer", self.truth))
        return out

    def high_rates(self) -> list[Case]:
        """2 MHz with white noise was refused as low-pass filtered (0.5 and 1 MHz were answered)."""
        scenario = Scenario.from_height(mass=30.0, height=0.2, pressure_gauge=200e3)
        path = self.path("rate2MHz.h5")
        if not path.exists():
            sim = simulate(scenario, duration=0.05, sample_rate=4e6)
            quiet = np.zeros(40000)
            rec = apply_sensors({"contact_force": np.r_[quiet, sim.contact_force],
                                 "piston_acceleration": np.r_[quiet, sim.a2]}, input_rate=4e6, sample_rate=2e6,
                                start_time=-0.01, noise=0.01, seed=0)
            write_recording(rec, path)
        truth = (30.0, scenario.velocity)
        return [Case("high sample rates", "identify: 2 MHz, white noise", ["identify", str(path), "--json"], "answer",
                     truth, sigmas=3.0)]

    def special_targets(self) -> list[Case]:
        """Targets that are no regular files, replaced by a file under the overwrite flag before."""
        folder = self.path("special")
        folder.mkdir(exist_ok=True)
        pipe, device = folder / "pipe.h5", folder / "null.csv"
        if not pipe.exists():
            os.mkfifo(pipe)
        if not device.is_symlink():
            device.symlink_to(os.devnull)
        cases = {"record --out a named pipe, --overwrite": ["record", "--out", str(pipe), "--overwrite"],
                 "record --out a link to /dev/null, --overwrite": ["record", "--out", str(device), "--overwrite"],
                 "simulate --out a named pipe, --overwrite": ["simulate", "--out", str(pipe), "--overwrite"],
                 "map build --out a named pipe, --overwrite": ["map", "build", "--out", str(pipe), "--grid", "3",
                                                               "--overwrite"],
                 "simulate --out x.csv": ["simulate", "--out", str(folder / "x.csv")]}
        return [Case("special output targets", label, argv, protect=(pipe, device),
                     reason="expected one of .h5, .hdf5" if label.endswith("x.csv") else "is not a regular file")
                for label, argv in cases.items()]


    # a lab engineer's second day: slips the physics shows, records of other machines, a 1 MHz DAQ ------------------
    def unit_slips(self) -> list[Case]:
        """An acceleration in g under an [m/s^2] header (M1 3.5 times too large, silently), a time column in ms under
        [s] (read as a 50 Hz, 70 s record), an accelerometer mounted the other way."""
        time = self.rec.time - self.rec.time[0]
        g = write_csv(self.path("slip-g.csv"), {"time [s]": time, "force [N]": self.f,
                                                "acc [m/s^2]": self.a / 9.80665})
        ms = write_csv(self.path("slip-ms.csv"), {"time [s]": time * 1e3, "force [N]": self.f, "acc [m/s^2]": self.a})
        flipped = self.recording("slip-flipped.h5", self.f, -self.a)
        return [Case("unit slips", "acceleration in g under [m/s^2]", ["identify", str(g), "--json"], "answer",
                     self.truth),
                Case("unit slips", "acceleration in g, --acceleration-unit g", ["identify", str(g), "--json",
                                                                                "--acceleration-unit", "g"], "answer",
                     self.truth, sigmas=3.0),
                Case("unit slips", "time in ms under [s]", ["identify", str(ms), "--json"], reason="--time-unit ms"),
                Case("unit slips", "time in ms, --time-unit ms", ["identify", str(ms), "--json", "--time-unit", "ms"],
                     "answer", self.truth, sigmas=3.0),
                *self._pair("unit slips", "accelerometer mounted the other way", flipped, "refuse", self.truth,
                            reason="--flip-acceleration")]

    def other_machines(self) -> list[Case]:
        """A guided drop weight (tests/drop_weight.py): refused in one line, whatever the accelerometer's sign."""
        from drop_weight import drop_weight

        heavy, light = drop_weight(mass=20.0, velocity=3.0, stiffness=4e7), drop_weight(mass=5.0, velocity=2.0,
                                                                                          stiffness=3e5, seed=1)
        out = []
        for label, rec in (("20 kg striker", heavy), ("5 kg striker, ringing", light)):
            path = write_recording(rec, self.path(f"striker-{rec.truth('mass_kg'):g}.h5"), overwrite=True)
            out += self._pair("other machines", label, path, "refuse", reason="not a drop on a gas-spring rod")
            out.append(Case("other machines", f"paper: {label}", ["identify", str(path), "--variant", "paper"],
                            reason="not a drop on a gas-spring rod"))
            out.append(Case("other machines", f"inspect: {label}", ["inspect", str(path)], "answer"))
        return out

    def clipped_in_flight(self) -> list[Case]:
        """The acceleration's minimum clipped at 95 % at 100 kHz: the rail is touched for a sample in the first
        flights and held for 82 samples in a later one (V0 3.1 standard errors off, silently)."""
        rec = record(Scenario(mass=30.0, velocity=1.98, pressure_gauge=200e3), sample_rate=100e3, duration=0.1,
                     noise=0.01, seed=1, pre_trigger=0.02)
        a = rec.piston_acceleration
        path = write_recording(Recording(sample_rate=rec.sample_rate, start_time=rec.start_time, metadata=rec.metadata,
                                         channels={"contact_force": rec.contact_force,
                                                   "piston_acceleration": np.maximum(a, 0.95 * a.min())}),
                               self.path("aclip-flight.h5"), overwrite=True)
        return self._pair("clipped in a flight", "minimum at 95 %, 100 kHz", path, "refuse", (30.0, 1.98),
                          reason="piston_acceleration is saturated")

    def megahertz(self) -> list[Case]:
        """A 1 MHz DAQ: the vertex fit reached 128 samples (128 µs) of turning points a millisecond wide (M1 -6.4,
        V0 +5.1 standard errors, silently; another seed refused)."""
        out = []
        for seed in (1, 2):
            path = self.path(f"rate1MHz-{seed}.h5")
            if not path.exists():
                main(["record", "--sample-rate", "1MHz", "--noise", "1%", "--seed", str(seed), "--out", str(path)])
            out.append(Case("1 MHz DAQ", f"identify: seed {seed}", ["identify", str(path), "--json"], "answer",
                            (30.0, math.sqrt(2 * 9.80665 * 0.2)), sigmas=3.0))
        return out

    def bare_command(self) -> list[Case]:
        """``impactometer`` alone exited 2 under click 8.2 and later: its help, exit 0."""
        return [Case("bare command", "impactometer", [], "answer")]


#: channel names that do not survive every format, and the formats they are written to
NAMES = ("a,b", "a;b", 'say "hi"', "a\nb", "a/b", ".", "force [kN]", " force", "time")


def round_trips(folder: Path) -> list[tuple[Case, str, str]]:
    """Recordings with awkward channel names written and read back: handled where the channel comes back with its
    name and samples, or the writer refuses it in one line; data loss otherwise (a CSV header that could not be
    read back, an HDF5 channel that became a subgroup and disappeared)."""
    folder = Path(folder) / "names"
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    values = np.array([1.0, 2.0, 3.0])
    for fmt in ("csv", "h5", "tdms"):
        for k, name in enumerate(NAMES):
            case = Case("channel names", f"{fmt}: {name!r}", [])
            path = folder / f"n{k}.{fmt}"
            rec = Recording(sample_rate=1e3, channels={"contact_force": np.arange(3.0), name: values})
            try:
                write_recording(rec, path, overwrite=True)
            except ImpactometerError as exc:
                text = str(exc)
                out.append((case, "handled" if "\n" not in text else "unhandled", text[:200]))
                continue
            try:
                back = read_recording(path)
            except ImpactometerError as exc:
                out.append((case, "data-loss", f"written, but not read back: {str(exc)[:160]}"))
                continue
            same = list(back.channels) == list(rec.channels) and np.array_equal(back.channels.get(name), values)
            out.append((case, "handled" if same else "data-loss",
                        "read back as written" if same else f"read back as {list(back.channels)}"))
    return out
