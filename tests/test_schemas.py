#!/usr/bin/python3
"""JSON output against schemas/: runs the mimic binary (synth -> ingest ->
info/list) and validates every JSON document it writes or prints with
Debian's python3-jsonschema. Prints 'N passed, N failed'."""
import json
import os
import subprocess
import sys
import tempfile

import jsonschema

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MIMIC = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("MIMIC_BIN", "mimic")


def load(name):
    with open(os.path.join(ROOT, "schemas", name)) as f:
        return json.load(f)


SCHEMAS = {s["$id"]: s for s in map(load, ["info.schema.json", "list.schema.json", "landmarks.schema.json"])}


def validator(schema_id):
    schema = SCHEMAS[schema_id]
    resolver = jsonschema.RefResolver(base_uri=schema_id, referrer=schema, store=SCHEMAS)
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema, resolver=resolver)


def run(*args):
    p = subprocess.run([MIMIC, *args], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"mimic {' '.join(args)} exited {p.returncode}: {p.stderr.strip()}")
    return p.stdout


def main():
    passed = failed = 0
    with tempfile.TemporaryDirectory(prefix="mimic-schemas-") as d:
        data, store, empty = os.path.join(d, "bodies"), os.path.join(d, "store"), os.path.join(d, "empty")
        run("synth", "--out", data, "--subjects", "2", "--poses", "2", "--vertices", "1500")
        run("ingest", "--store", store, data)
        # an empty store: connectivity and landmarks are null
        os.makedirs(empty)
        subprocess.run([MIMIC, "ingest", "--store", empty, os.path.join(d, "nothing")], capture_output=True)
        with open(os.path.join(data, "landmarks.json")) as f:
            landmarks = json.load(f)
        cases = [
            ("/mimic/schemas/info.schema.json", json.loads(run("info", "--store", store, "--json")), "info"),
            ("/mimic/schemas/info.schema.json", json.loads(run("info", "--store", empty, "--json")), "info (empty store)"),
            ("/mimic/schemas/list.schema.json", json.loads(run("list", "--store", store, "--json")), "list"),
            ("/mimic/schemas/list.schema.json", json.loads(run("list", "--store", store, "--pose", "9", "--json")), "list (none)"),
            ("/mimic/schemas/landmarks.schema.json", landmarks, "synth landmarks.json"),
        ]
        for schema_id, doc, what in cases:
            errors = list(validator(schema_id).iter_errors(doc))
            if errors:
                failed += 1
                print(f"FAIL {what}: {errors[0].message} at {list(errors[0].absolute_path)}")
            else:
                passed += 1
                print(f"ok   {what}")
        # the schemas must also reject what they should
        bad = json.loads(run("info", "--store", store, "--json"))
        bad["templates"] = "4"
        if list(validator("/mimic/schemas/info.schema.json").iter_errors(bad)):
            passed += 1
            print("ok   info schema rejects a string template count")
        else:
            failed += 1
            print("FAIL info schema accepted a string template count")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
