#!/usr/bin/env python3
"""Check, and on request rewrite, the docs' figures listed in docs/figures.toml.

The same check as `cargo test --test docs_figures` (the test stays the judge), run in
parallel on a release binary, with two regeneration aids:

  --apply  replaces a stale text in its doc where exactly one place in the doc has the
           same words with other numbers (a sentence, a templated row of the same
           labels), and a stale `rows_of` table as a whole: the doc's table whose rows
           have the same labels in the same order (where several have, the manifest's
           order of their figures is the doc's); anything else is reported for a hand
           edit;
  --bless  copies a drawn image over the doc's.

    cargo build --release -p pma-exo --no-default-features
    python3 tools/figures.py --bin target/release/pma-exo            # fast figures
    python3 tools/figures.py --bin target/release/pma-exo --slow -j 1 --filter treadmill
"""
import argparse
import concurrent.futures as cf
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NUMBER = r"-?\d[\d,]*(?:\.\d+)?"


def at(value, path):
    for key in path.split("."):
        value = value[int(key)] if key.isdigit() else value[key]
    return value


def expand(template, data):
    def field(match):
        expr = match.group(1)
        if ":." in expr:
            expr, digits = expr.split(":.")
            factor = 1.0
            if "*" in expr:
                expr, f = expr.split("*")
                factor = float(f)
            return f"{float(at(data, expr)) * factor:.{int(digits)}f}"
        return str(at(data, expr))

    return re.sub(r"\{([^{}]+)\}", field, template)


def table_rows(text):
    lines = text.splitlines()
    rows = []
    for i, line in enumerate(lines):
        header = i + 1 < len(lines) and lines[i + 1].startswith("|---")
        if line.startswith("| ") and not line.startswith("|---") and not header:
            rows.append(line)
    return rows


def write_inputs(manifest, work):
    for f in manifest.get("file", []):
        with open(os.path.join(ROOT, f["from"])) as fh:
            text = fh.read()
        for old, new in f.get("replace", []):
            if old not in text:
                sys.exit(f"{f['from']}: no `{old}` (file {f['name']})")
            text = text.replace(old, new)
        with open(os.path.join(work, f["name"]), "w") as fh:
            fh.write(text)


def run(binary, command, work, exit_code):
    args = [a.replace("{dir}", work) for a in command]
    out = subprocess.run([binary, *args], cwd=work, capture_output=True, text=True)
    ok = out.returncode == exit_code if exit_code is not None else out.returncode in (0, 3)
    if not ok:
        return None, f"exit {out.returncode}, expected {exit_code}: {out.stderr.strip()[-400:]}"
    lines = out.stdout.strip().splitlines()
    try:
        return (json.loads(lines[-1]) if lines else None), None
    except json.JSONDecodeError:
        return None, None


def expected_texts(figure, data, work):
    texts = [expand(t, data) for t in figure.get("text", [])]
    if figure.get("rows_of"):
        with open(figure["rows_of"].replace("{dir}", work)) as fh:
            texts += table_rows(fh.read())
    return texts


def skeleton_pattern(expected):
    """A regex matching `expected` with any number where it has one."""
    parts = re.split(f"({NUMBER})", expected)
    return "".join(NUMBER if i % 2 else re.escape(p) for i, p in enumerate(parts))


def row_labels(row):
    """The cells of a table row that name it rather than measure it: its first cell, and its
    second where that is a count or a percentage (a controller and a support, a scenario
    and a check); an envelope's row: its mode, speed, support and mass."""
    cells = [c.strip() for c in row.strip().strip("|").split("|")]
    if cells[0] in ("position", "impedance", "admittance", "path", "transparent") and len(cells) >= 9:
        return (cells[0], cells[1], cells[3], cells[4])
    if len(cells) > 1 and re.fullmatch(r"\d+( %| \(shipped\))?", cells[1]):
        return (cells[0], cells[1])
    return (cells[0],)


def table_row_key(row):
    """A row's labels and width: what a `rows_of` table's rows are found by in a doc."""
    return (row.strip().strip("|").count("|") + 1, *row_labels(row))


def row_groups(text):
    """The tables of a `rows_of` file, each as its list of rows."""
    groups, current = [], []
    rows = set(table_rows(text))
    for line in text.splitlines():
        if line in rows:
            current.append(line)
        elif current:
            groups.append(current)
            current = []
    return groups + ([current] if current else [])


def table_blocks(lines, labels):
    """Where a whole table (header and separator above, nothing of its width below; in a
    list item, indented) with these row labels, in order, starts in `lines`."""
    n = len(labels)
    flat = [line.lstrip() for line in lines]
    return [j for j in range(2, len(lines) - n + 1)
            if flat[j - 1].startswith("|---")
            and (j + n == len(lines) or not flat[j + n].startswith("|"))
            and all(flat[j + i].startswith("| ") and table_row_key(flat[j + i]) == labels[i]
                    for i in range(n))]


def shared_cells(lines, j, rows):
    return sum(a == b for i, r in enumerate(rows)
               for a, b in zip(lines[j + i].strip().split("|"), r.split("|")))


def apply_tables(doc_path, tables):
    """Replaces each stale `rows_of` table. `tables` lists (rank, count, rows): the table's
    rank among the tables this run checked in the doc with the same labels, in manifest
    order, and their count. Where the doc has one table with those labels it is replaced;
    where it has `count`, the one at `rank` (the manifest lists a doc's figures in the
    doc's order); where it has more, the one sharing the most cells with the new rows;
    otherwise it is left for a hand edit."""
    with open(doc_path) as fh:
        lines = fh.read().split("\n")
    left = []
    for rank, count, rows in tables:
        blocks = table_blocks(lines, [table_row_key(r) for r in rows])
        shared = [shared_cells(lines, j, rows) for j in blocks]
        best = [j for j, n in zip(blocks, shared) if n == max(shared, default=-1)]
        if len(blocks) == 1 or len(blocks) == count:
            j = blocks[0] if len(blocks) == 1 else blocks[rank]
        elif len(best) == 1:
            # More tables with these labels than this run checked (a history kept beside
            # it): the one sharing the most cells with the new rows.
            j = best[0]
        else:
            j = None
        if j is not None:
            indent = lines[j][: len(lines[j]) - len(lines[j].lstrip())]
            lines[j:j + len(rows)] = [indent + r for r in rows]
        else:
            left.append((rows[0], len(blocks)))
    tmp = doc_path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write("\n".join(lines))
    os.replace(tmp, doc_path)
    return left


def apply(doc_path, stale):
    with open(doc_path) as fh:
        text = fh.read()
    left = []
    for expected in stale:
        matches = list(re.finditer(skeleton_pattern(expected), text))
        if expected.startswith("| "):
            # A row of other labels is another row, whatever its numbers.
            matches = [m for m in matches if row_labels(m.group(0)) == row_labels(expected)]
        # Among several places, the one sharing the most numbers with the new text
        # (a row's label, its step), where one alone does.
        numbers = re.findall(NUMBER, expected)
        scores = [sum(a == b for a, b in zip(numbers, re.findall(NUMBER, m.group(0))))
                  for m in matches]
        best = [m for m, s in zip(matches, scores) if s == max(scores, default=0)]
        if len(best) == 1:
            m = best[0]
            text = text[: m.start()] + expected + text[m.end():]
        else:
            left.append((expected, len(matches)))
    tmp = doc_path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write(text)
    os.replace(tmp, doc_path)
    return left


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bin", required=True)
    p.add_argument("--slow", action="store_true", help="the slow figures instead")
    p.add_argument("--filter", action="append", default=[],
                   help="only commands containing this (repeat: all must match)")
    p.add_argument("--doc", action="append", default=[],
                   help="only the figures of this doc, e.g. docs/patient.md (repeat: any)")
    p.add_argument("--apply", action="store_true")
    p.add_argument("--bless", action="store_true")
    p.add_argument("-j", type=int, default=os.cpu_count())
    a = p.parse_args()
    binary = os.path.abspath(a.bin)
    with open(os.path.join(ROOT, "docs/figures.toml"), "rb") as fh:
        manifest = tomllib.load(fh)
    work = tempfile.mkdtemp(prefix="pma-exo-figures-")
    write_inputs(manifest, work)

    def chosen(item):
        line = " ".join(item["command"])
        return (item.get("slow", False) == a.slow and all(f in line for f in a.filter)
                and (not a.doc or item.get("doc") in a.doc))

    figures = [f for f in manifest["figure"] if chosen(f)]
    images = [i for i in manifest.get("image", []) if chosen(i)]
    stale, failed, checked, n_stale = {}, [], 0, 0
    # Each `rows_of` figure's tables, by doc: (the figure's place in the manifest, rows).
    tables, order = {}, {id(f): i for i, f in enumerate(figures)}
    # A command that several figures share runs once (two `paper --out DIR` at once would
    # refuse each other's directory).
    runs = {}
    for item in figures + images:
        runs.setdefault((tuple(item["command"]), item.get("exit")), []).append(item)
    # Commands that write a file (`--out`) first: others may read it (`size --out` writes
    # the muscles a later `simulate` runs).
    done = []
    for writes in (True, False):
        with cf.ThreadPoolExecutor(max_workers=a.j) as pool:
            jobs = {pool.submit(run, binary, list(cmd), work, code): items
                    for (cmd, code), items in runs.items() if ("--out" in cmd) == writes}
            done += [(item, job.result()) for job in cf.as_completed(jobs)
                     for item in jobs[job]]
    # The tables of `rows_of` figures that failed: each keeps its rank among its doc's tables
    # with the same labels, and is never replaced (a failed figure's table counted out of
    # the ranks shifted a stale table onto its neighbour's place, stop 73).
    kept = set()

    def add_tables(item):
        """Reads a `rows_of` figure's tables into its doc's ranks; returns them."""
        with open(item["rows_of"].replace("{dir}", work)) as fh:
            groups = row_groups(fh.read())
        tables.setdefault(item["doc"], []).extend((order[id(item)], g) for g in groups)
        return groups

    for item, (data, error) in done:
        cmd = " ".join(item["command"])
        if error:
            failed.append(f"FAILED pma-exo {cmd}: {error}")
            print(failed[-1], flush=True)
            if os.path.exists(item.get("rows_of", "").replace("{dir}", work)):
                kept.update(id(g) for g in add_tables(item))
            continue
        if "drawn" in item:
            checked += 1
            drawn = item["drawn"].replace("{dir}", work)
            path = os.path.join(ROOT, item["path"])
            with open(drawn, "rb") as fh:
                new = fh.read()
            same = os.path.exists(path) and open(path, "rb").read() == new
            if a.bless and not same:
                shutil.copyfile(drawn, path)
                print(f"{item['path']}: redrawn", flush=True)
            elif not same:
                stale.setdefault(item["path"], []).append(None)
                n_stale += 1
                print(f"{item['path']}: differs from `pma-exo {cmd}`", flush=True)
            continue
        if data is None and any("{" in t for t in item.get("text", [])):
            failed.append(f"FAILED pma-exo {cmd}: its last line of output is not JSON")
            print(failed[-1], flush=True)
            continue
        with open(os.path.join(ROOT, item["doc"])) as fh:
            doc = fh.read()
        try:
            texts = list(expected_texts(item, data, work))
        except (KeyError, IndexError, TypeError, ValueError) as e:
            # A field the text reads is missing or null (a run that failed where the doc
            # says it walked): the figure cannot be checked, which is a failure.
            failed.append(f"FAILED pma-exo {cmd}: a field the text reads is absent ({e!r})")
            print(failed[-1], flush=True)
            continue
        table = set()
        if item.get("rows_of"):
            table = {r for g in add_tables(item) for r in g}
        for expected in texts:
            checked += 1
            if expected not in doc:
                n_stale += 1
                if expected not in table:
                    stale.setdefault(item["doc"], []).append(expected)
                print(f"{item['doc']}: should say `{expected}` (`pma-exo {cmd}`)", flush=True)
    doc_tables = {
        doc: [g for _, g in sorted(groups, key=lambda t: t[0])]
        for doc, groups in tables.items()
    }
    print(f"{n_stale} of {checked} stale, {len(failed)} failed")
    if a.apply:
        for doc, groups in doc_tables.items():
            with open(os.path.join(ROOT, doc)) as fh:
                lines = {line.strip() for line in fh.read().split("\n")}
            labels = [tuple(table_row_key(r) for r in g) for g in groups]
            todo = [(labels[:i].count(labels[i]), labels.count(labels[i]), g)
                    for i, g in enumerate(groups)
                    if id(g) not in kept and any(r not in lines for r in g)]
            if todo:
                left = apply_tables(os.path.join(ROOT, doc), todo)
                print(f"{doc}: {len(todo) - len(left)} tables replaced")
                for row, n in left:
                    print(f"  TABLE NOT REPLACED ({n} with its labels): `{row}`")
        for doc, texts in stale.items():
            texts = [t for t in texts if t is not None]
            if not texts:
                continue
            left = apply(os.path.join(ROOT, doc), texts)
            print(f"{doc}: {len(texts) - len(left)} applied")
            for expected, n in left:
                print(f"  NOT APPLIED ({n} places): `{expected}`")
    shutil.rmtree(work, ignore_errors=True)
    return 1 if (n_stale and not a.apply) or failed else 0


if __name__ == "__main__":
    sys.exit(main())
