#!/usr/bin/python3
"""Markdown tables of the dynamic_reconfigure parameters, generated from cfg/*.cfg.

The cfg files are read as Python source (ast), never run: every `gen.add(name, type, level, description,
default, min, max)` call becomes a table row (parameter, type, default, range, description). An enum
(`edit_method=gen.enum([...])`) gives its values as the range.

A document holds a generated table between two marker comments:

    <!-- param-table: LaserMapping.cfg -->                       every parameter of the file
    <!-- param-table: LaserMapping.cfg cube_size eviction_radius --> only these, in this order
    ...
    <!-- /param-table -->

Usage: param_tables.py                       print the table of every cfg file, with its markers
       param_tables.py --check FILE...       exit 1 and name each table that differs from the generated one
       param_tables.py --write FILE...       rewrite the tables in place
Options: --cfg-dir DIR (default: cfg/ beside this script's folder).
Debian's python3 and its standard library only.
"""
import argparse
import ast
import glob
import os
import re
import sys

TYPES = {"double_t": "double", "int_t": "int", "bool_t": "bool", "str_t": "string"}
BEGIN = re.compile(r"^<!-- param-table: (\S+\.cfg)((?: [A-Za-z_]\w*)*) -->$")
END = "<!-- /param-table -->"


class CfgError(Exception):
    pass


def literal(node, names, where):
    """The value of a literal, or of a module-level name bound to one."""
    if isinstance(node, ast.Name) and node.id in names:
        return names[node.id]
    try:
        return ast.literal_eval(node)
    except ValueError:
        raise CfgError("%s: not a literal: %s" % (where, ast.dump(node)))


def is_call(node, method):
    """node is `<something>.method(...)`, e.g. gen.add(...)."""
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == method)


def enum_values(node, where):
    """The constant values of a gen.enum([gen.const(name, type, value, description), ...], description)."""
    if not is_call(node, "enum") or not node.args or not isinstance(node.args[0], ast.List):
        raise CfgError("%s: edit_method is not a gen.enum([...]) call" % where)
    values = []
    for const in node.args[0].elts:
        if not is_call(const, "const") or len(const.args) < 3:
            raise CfgError("%s: an enum entry is not gen.const(name, type, value, description)" % where)
        values.append(ast.literal_eval(const.args[2]))
    return values


def parse_cfg(path):
    """The rows of one cfg file, in file order: dicts of name, type, default, min, max, description, enum."""
    source = open(path, encoding="utf-8").read()
    tree = ast.parse(source, filename=path)
    names, enums, rows = {}, {}, []
    for stmt in tree.body:
        # Module-level constants (levels) and enums bound to a name.
        if isinstance(stmt, ast.Assign) and len(stmt.targets) == 1 and isinstance(stmt.targets[0], ast.Name):
            target = stmt.targets[0].id
            if is_call(stmt.value, "enum"):
                enums[target] = stmt.value
            else:
                try:
                    names[target] = ast.literal_eval(stmt.value)
                except ValueError:
                    pass
            continue
        if not (isinstance(stmt, ast.Expr) and is_call(stmt.value, "add")):
            continue
        call = stmt.value
        where = "%s:%d" % (os.path.basename(path), call.lineno)
        if len(call.args) < 5:
            raise CfgError("%s: gen.add needs name, type, level, description, default" % where)
        type_node = call.args[1]
        if not isinstance(type_node, ast.Name) or type_node.id not in TYPES:
            raise CfgError("%s: unknown parameter type" % where)
        row = {
            "name": literal(call.args[0], names, where),
            "type": TYPES[type_node.id],
            "description": literal(call.args[3], names, where),
            "default": literal(call.args[4], names, where),
            "min": literal(call.args[5], names, where) if len(call.args) > 5 else None,
            "max": literal(call.args[6], names, where) if len(call.args) > 6 else None,
            "enum": None,
        }
        for keyword in call.keywords:
            if keyword.arg in ("min", "max", "default", "description"):
                row[keyword.arg] = literal(keyword.value, names, where)
            elif keyword.arg == "edit_method":
                node = keyword.value
                if isinstance(node, ast.Name) and node.id in enums:
                    node = enums[node.id]
                row["enum"] = enum_values(node, where)
        rows.append(row)
    if not rows:
        raise CfgError("%s: no gen.add(...) call found" % path)
    return rows


def show(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def cell(text):
    return text.replace("|", "\\|")


def table(rows):
    lines = ["| parameter | type | default | range | description |", "|---|---|---|---|---|"]
    for r in rows:
        if r["enum"] is not None:
            span = ", ".join(show(v) for v in r["enum"])
        elif r["min"] is not None and r["max"] is not None:
            span = "%s to %s" % (show(r["min"]), show(r["max"]))
        else:
            span = "-"
        lines.append("| `%s` | %s | %s | %s | %s |" % (r["name"], r["type"], cell(show(r["default"])), cell(span),
                                                       cell(r["description"])))
    return lines


def generated(cfg_dir, cfg_name, wanted):
    """The table lines of cfg_name, restricted to the parameters in `wanted` (all when empty)."""
    path = os.path.join(cfg_dir, cfg_name)
    if not os.path.isfile(path):
        raise CfgError("%s: no such cfg file" % path)
    rows = parse_cfg(path)
    if wanted:
        by_name = {r["name"]: r for r in rows}
        unknown = [w for w in wanted if w not in by_name]
        if unknown:
            raise CfgError("%s has no parameter %s" % (cfg_name, ", ".join(unknown)))
        rows = [by_name[w] for w in wanted]
    return table(rows)


def blocks(lines, path):
    """(begin index, end index, cfg name, wanted names) of every marked table in a document."""
    found, i = [], 0
    while i < len(lines):
        m = BEGIN.match(lines[i].strip())
        if m:
            j = i + 1
            while j < len(lines) and lines[j].strip() != END:
                if BEGIN.match(lines[j].strip()):
                    raise CfgError("%s:%d: a param-table opens before the one of line %d closes" % (path, j + 1, i + 1))
                j += 1
            if j == len(lines):
                raise CfgError("%s:%d: param-table without %s" % (path, i + 1, END))
            found.append((i, j, m.group(1), m.group(2).split()))
            i = j
        i += 1
    return found


def process(path, cfg_dir, write):
    """Returns the list of differing tables (labels); rewrites them when `write`."""
    text = open(path, encoding="utf-8").read()
    lines = text.split("\n")
    marked = blocks(lines, path)
    if not marked:
        raise CfgError("%s: no <!-- param-table: ... --> markers" % path)
    differing = []
    out, last = [], 0
    for begin, end, cfg_name, wanted in marked:
        expected = generated(cfg_dir, cfg_name, wanted)
        present = [line.rstrip() for line in lines[begin + 1:end] if line.strip()]
        label = "%s:%d (%s%s)" % (path, begin + 1, cfg_name, (" " + " ".join(wanted)) if wanted else "")
        if present != expected:
            differing.append(label)
        if present != expected and not write:
            shown = set(present)
            for line in expected:
                if line not in shown:
                    print("  expected: %s" % line)
            exp = set(expected)
            for line in present:
                if line not in exp:
                    print("  found:    %s" % line)
        out.extend(lines[last:begin + 1])
        out.extend(expected + [""])  # the table right after the opening marker, a blank line before the closing
        last = end
    out.extend(lines[last:])
    if write:
        new = "\n".join(out)
        if new != text:
            with open(path, "w", encoding="utf-8") as f:
                f.write(new)
    return differing


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description="Parameter tables from cfg/*.cfg")
    parser.add_argument("--cfg-dir", default=os.path.join(os.path.dirname(here), "cfg"))
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--check", nargs="+", metavar="FILE")
    mode.add_argument("--write", nargs="+", metavar="FILE")
    args = parser.parse_args()
    try:
        if not args.check and not args.write:
            for path in sorted(glob.glob(os.path.join(args.cfg_dir, "*.cfg"))):
                name = os.path.basename(path)
                print("<!-- param-table: %s -->" % name)
                print("\n".join(generated(args.cfg_dir, name, [])))
                print("\n%s\n" % END)
            return 0
        failed = False
        for path in args.check or args.write:
            for label in process(path, args.cfg_dir, write=bool(args.write)):
                if args.write:
                    print("rewritten: %s" % label)
                else:
                    print("DIFFERS: %s is not what cfg/ generates (fix: %s --write %s)"
                          % (label, os.path.relpath(__file__), path))
                    failed = True
        if args.check and not failed:
            print("param tables: every table in %s is what cfg/ generates" % ", ".join(args.check))
        return 1 if failed else 0
    except (CfgError, OSError, SyntaxError) as e:
        print("param_tables: %s" % e, file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
