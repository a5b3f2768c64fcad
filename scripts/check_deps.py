#!/usr/bin/python3
"""Dependency self-check: everything the build, the tests, the scripts and the README use must come from a
Debian package that the project installs (scripts/common.sh: ALOAM_DEBIAN_PACKAGES) or from that list's
dependency closure, or from the packages every Debian system has (Essential: yes, Priority: required).

What it checks, each against the closure:
- every Python module imported under test/ and scripts/ (resolved by Debian's /usr/bin/python3, without any
  workspace on the path), except this repository's own modules;
- every command the shell scripts, .ci/run, the Python test nodes (subprocess calls) and the shell blocks and
  inline commands of the README and docs/ run, and every `rosrun PKG EXE` / `roslaunch PKG FILE` they name;
- every ROS package a launch or rostest file starts a node of or includes a file from;
- every find_package() and catkin component in the CMakeLists.txt files.

Usage: check_deps.py REPO_ROOT PACKAGE...   (exit 0: all resolved; 1: what is missing, one line each)
       check_deps.py --provided PKG PACKAGE...  (exit 0 if PKG is in the dependency closure of PACKAGE...)
It reads the project's own files only (those git lists, or outside git all but build trees and caches, with
exact suffixes) and dpkg's database; it installs nothing and asks no package server. A file that is not UTF-8
is reported as a problem, and a crash of the check is a failure.
"""
import ast
import glob
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import traceback
from collections import defaultdict

# Shell words that are not commands of a package: builtins, keywords and this project's shell functions
# (the functions are found in the scripts themselves; see shell_functions).
SHELL_WORDS = set("""
if then else elif fi for in while until do done case esac function select time coproc ! { } [ [[ ]] ]
. : source alias bg bind break builtin caller cd command compgen complete continue declare dirs disown echo
enable eval exec exit export false fc fg getopts hash help history jobs kill let local logout mapfile popd
printf pushd pwd read readarray readonly return set shift shopt suspend test times trap true type typeset
ulimit umask unalias unset wait
""".split())

# The C and C++ sources whose includes are checked (exact suffixes: a glob like *.[ch]* also takes *.cpython-*.pyc).
CXX_SUFFIXES = (".c", ".cc", ".cpp", ".cxx", ".h", ".hh", ".hpp", ".hxx")

# rosdep keys of what is not a ROS package of the same name.
PYTHON_KEYS = {"numpy": "python3-numpy", "matplotlib": "python3-matplotlib", "rospkg": "python3-rospkg",
               "yaml": "python3-yaml", "scipy": "python3-scipy"}
INCLUDE_KEYS = {"pcl": "libpcl-all-dev", "ceres": "libceres-dev", "Eigen": "eigen", "boost": "boost",
                "gtest": "gtest", "sys": None}
CMAKE_KEYS = {"Eigen3": "eigen", "Ceres": "libceres-dev", "PCL": "libpcl-all-dev", "GTest": "gtest"}
COMMAND_KEYS = {"rosrun": "rosbash", "roslaunch": "roslaunch", "rostest": "rostest", "rosbag": "rosbag",
                "rostopic": "rostopic", "rosservice": "rosservice", "rosnode": "rosnode", "rosparam": "rosparam",
                "roscore": "roslaunch", "catkin_make": "catkin", "catkin_test_results": "catkin"}


def is_ros_package(name):
    return os.path.exists("/usr/share/%s/package.xml" % name)


def run(cmd):
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, universal_newlines=True).stdout


class Debian:
    """dpkg's view: installed packages, their dependencies, and who owns a file."""

    def __init__(self):
        self.depends = {}
        self.provides = defaultdict(set)
        self.base = set()
        fmt = "${Package}\t${Status}\t${Essential}\t${Priority}\t${Pre-Depends}, ${Depends}\t${Provides}\n"
        for line in run(["dpkg-query", "-W", "-f=" + fmt]).splitlines():
            name, status, essential, priority, depends, provides = (line.split("\t") + [""] * 6)[:6]
            if not status.endswith("installed") or "not-installed" in status or "config-files" in status:
                continue
            self.depends[name] = depends
            for item in provides.split(","):
                if item.strip():
                    self.provides[item.split()[0]].add(name)
            if essential == "yes" or priority == "required":
                self.base.add(name)
        self.owners = None  # file -> package, read on first use
        self.by_name = None  # file name -> [(path, package)]

    def installed(self, name):
        return name in self.depends

    def resolve(self, name):
        """Installed packages that satisfy a dependency on `name` (itself or a provider)."""
        name = name.split(":")[0]
        found = {name} if self.installed(name) else set()
        return found | {p for p in self.provides.get(name, ()) if self.installed(p)}

    def closure(self, roots):
        seen, stack = set(), []
        for root in roots:
            stack.extend(self.resolve(root))
        while stack:
            pkg = stack.pop()
            if pkg in seen:
                continue
            seen.add(pkg)
            for alternative in self.depends.get(pkg, "").split(","):
                choices = [c.strip().split()[0] for c in alternative.split("|") if c.strip()]
                for choice in choices:  # the first alternative that is installed satisfies it
                    satisfied = self.resolve(choice)
                    if satisfied:
                        stack.extend(satisfied)
                        break
        return seen

    def owner(self, path):
        """The package owning a file (following symbolic links and Debian's /bin -> /usr/bin merge)."""
        if self.owners is None:
            self.owners = self.file_index()
        candidates = [path, os.path.realpath(path)]
        for p in list(candidates):
            for a, b in (("/usr/bin/", "/bin/"), ("/usr/sbin/", "/sbin/"), ("/usr/lib/", "/lib/")):
                if p.startswith(a):
                    candidates.append(b + p[len(a):])
                elif p.startswith(b):
                    candidates.append(a + p[len(b):])
        for p in candidates:
            if p in self.owners:
                return self.owners[p]
        return None

    def named(self, basename):
        """(path, package) of every installed file with this name."""
        if self.owners is None:
            self.owners = self.file_index()
        if self.by_name is None:
            self.by_name = defaultdict(list)
            for path, package in self.owners.items():
                self.by_name[os.path.basename(path)].append((path, package))
        return self.by_name.get(basename, [])

    @staticmethod
    def file_index():
        """Every installed file and its package, read once from dpkg's file lists (what `dpkg-query -S`
        searches, at a fraction of its cost per query)."""
        owners = {}
        for listing in sorted(glob.glob("/var/lib/dpkg/info/*.list")):
            package = os.path.basename(listing)[:-len(".list")].split(":")[0]
            with open(listing, encoding="utf-8", errors="replace") as f:
                for line in f:
                    owners.setdefault(line.rstrip("\n"), package)
        return owners


class Check:
    def __init__(self, root, packages):
        self.root = root
        self.debian = Debian()
        listed = set(packages)
        self.not_installed = sorted(p for p in listed if not self.debian.resolve(p))
        self.allowed = self.debian.closure(listed) | self.debian.closure(self.debian.base)
        self.problems = []
        self.checked = defaultdict(int)
        self.used = defaultdict(set)  # rosdep key -> where package.xml must declare it (for the cross-check)

    def problem(self, text):
        self.problems.append(text)

    # ---- the project's files ------------------------------------------------------------------------
    def project_files(self):
        """Repository-relative paths of the project's files: what git tracks plus new files it does not
        ignore, or, outside a git work tree, every file but the build trees and caches. Build outputs,
        bytecode and editor files are never read."""
        if not hasattr(self, "_files"):
            listed = subprocess.run(["git", "-C", self.root, "ls-files", "-z", "--cached", "--others",
                                     "--exclude-standard"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
            if listed.returncode == 0:
                files = [f for f in listed.stdout.decode("utf-8", "surrogateescape").split("\0") if f]
            else:
                files = []
                skip = {".git", ".catkin_ws", "build", "out", "__pycache__", ".vscode", ".idea"}
                for top, dirs, names in os.walk(self.root):
                    dirs[:] = [d for d in dirs if d not in skip]
                    files += [os.path.relpath(os.path.join(top, n), self.root) for n in names]
            self._files = sorted(set(f for f in files if os.path.isfile(os.path.join(self.root, f))))
        return self._files

    def files(self, folders, suffixes, recursive=True):
        """Absolute paths of the project's files under `folders` (repository-relative, "" for the root)
        whose names end in one of `suffixes` exactly ("CMakeLists.txt" counts as a suffix too)."""
        out = []
        for rel in self.project_files():
            folder = os.path.dirname(rel)
            inside = any(folder == f or (recursive and f and folder.startswith(f + "/")) or
                         (recursive and not f) for f in folders)
            if inside and rel.endswith(tuple(suffixes)):
                out.append(os.path.join(self.root, rel))
        return out

    def read(self, path):
        """A project file's text; one that is not UTF-8 is a problem to report, not a crash."""
        try:
            with open(path, encoding="utf-8") as f:
                return f.read()
        except UnicodeDecodeError as e:
            self.problem("%s: not UTF-8 text (byte 0x%02x at offset %d); the check reads sources as UTF-8"
                         % (os.path.relpath(path, self.root), e.object[e.start], e.start))
        except OSError as e:
            self.problem("%s: cannot be read (%s)" % (os.path.relpath(path, self.root), e.strerror))
        return ""

    def expect_file(self, what, where, path):
        """`path` must be a file owned by an allowed package."""
        self.checked[what.split()[0]] += 1
        pkg = self.debian.owner(path)
        if pkg is None:
            self.problem("%s (%s): %s belongs to no Debian package" % (what, where, path))
        elif pkg not in self.allowed:
            self.problem("%s (%s): %s comes from %s, which is not in ALOAM_DEBIAN_PACKAGES nor its dependencies"
                         % (what, where, path, pkg))

    # ---- Python modules ------------------------------------------------------------------------------
    def python_modules(self):
        files = self.python_files()
        local = {os.path.splitext(os.path.basename(f))[0] for f in files} | {"aloam_nodelet"}
        modules = defaultdict(set)
        for path in files:
            try:
                tree = ast.parse(self.read(path), path)
            except SyntaxError as e:
                self.problem("%s: not valid Python (%s, line %s)" % (os.path.relpath(path, self.root), e.msg,
                                                                      e.lineno))
                continue
            for node in ast.walk(tree):
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                else:
                    continue
                for name in names:
                    top = name.split(".")[0]
                    if top not in local:
                        modules[top].add(os.path.relpath(path, self.root))
        # Resolve with Debian's interpreter and no workspace on the path, as a fresh shell would.
        script = ("import importlib.util, sys\n"
                  "for m in sys.argv[1:]:\n"
                  "    try:\n"
                  "        s = importlib.util.find_spec(m)\n"
                  "    except Exception:\n"
                  "        s = None\n"
                  "    print(m, (s.origin or '-') if s else 'MISSING')\n")
        env = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/tmp")}
        out = subprocess.run(["/usr/bin/python3", "-c", script] + sorted(modules), env=env,
                             stdout=subprocess.PIPE, universal_newlines=True).stdout
        for line in out.splitlines():
            name, origin = line.split(" ", 1)
            where = ", ".join(sorted(modules[name])[:2])
            if origin == "MISSING":
                self.checked["python"] += 1
                self.problem("python module %s (%s): not importable by /usr/bin/python3" % (name, where))
            elif origin in ("built-in", "frozen", "-"):
                self.checked["python"] += 1
            else:
                self.expect_file("python module " + name, where, origin)
                key = PYTHON_KEYS.get(name, name if is_ros_package(name) else None)
                if key:
                    self.used[key].add(where)

    # ---- commands ------------------------------------------------------------------------------------
    def python_files(self):
        return sorted(self.files(["test"], [".py"]) + self.files(["scripts"], [".py"], recursive=False))

    def shell_files(self):
        files = self.files(["scripts"], [".sh"], recursive=False) + self.files(["test"], [".sh"])
        files += self.files([".ci"], [".ci/run"], recursive=False)
        return sorted(set(files))

    @staticmethod
    def shell_functions(texts):
        names = set()
        for text in texts:
            names |= set(re.findall(r"^\s*(?:function\s+)?([A-Za-z_][\w-]*)\s*\(\)", text, re.M))
        return names

    @staticmethod
    def code_of(line):
        """A shell line without its data: single-quoted text and comments dropped, double-quoted text
        reduced to the command substitutions inside it."""
        out, i, n = [], 0, len(line)
        while i < n:
            c = line[i]
            if c == "\\":
                i += 2
            elif c == "'":
                j = line.find("'", i + 1)
                i = n if j < 0 else j + 1
                out.append("''")
            elif c == '"':
                i += 1
                while i < n and line[i] != '"':
                    if line[i] == "\\":
                        i += 2
                    elif line.startswith("$(", i) and not line.startswith("$((", i):
                        depth, j = 1, i + 2
                        while j < n and depth:
                            depth += {"(": 1, ")": -1}.get(line[j], 0)
                            j += 1
                        out.append(" ; " + line[i + 2:j - 1] + " ; ")
                        i = j
                    else:
                        i += 1
                i += 1
                out.append('""')
            elif c == "#" and (i == 0 or line[i - 1] in " \t;"):
                break
            else:
                out.append(c)
                i += 1
        return "".join(out)

    @classmethod
    def shell_commands(cls, text):
        """First words of the simple commands in a shell text (heuristic: heredocs, array literals,
        arithmetic, comments and quoted data are left out)."""
        text = re.sub(r"^\s*#.*$", "", text, flags=re.M)  # comment lines
        text = re.sub(r"\b\w+=\((.*?)\)", "", text, flags=re.S)  # array literals
        text = re.sub(r"\\\n", " ", text)                      # continued lines
        commands = []
        heredoc = None
        for raw in text.splitlines():
            if heredoc:
                if raw.strip() == heredoc:
                    heredoc = None
                continue
            m = re.search(r"<<-?\s*['\"]?(\w+)['\"]?", raw)
            if m:
                heredoc = m.group(1)
            line = re.sub(r"\$\(\((.*?)\)\)", "0", cls.code_of(raw))
            line = re.sub(r"^\s*\(?[\w|*.\"'-]+\)\s", " ", line)  # a case pattern: "name) command ;;"
            line = re.sub(r"\[\[?[^\]]*\]\]?", "", line)  # test expressions
            for part in re.split(r"\|\||&&|[|;&]|\$\(|<\(|`|\(|\)|\bthen\b|\bdo\b|\belse\b|\btime\b", line):
                words = part.split()
                while words and (re.match(r"^[A-Za-z_]\w*=", words[0]) or
                                 words[0] in ("!", "{", "}", "if", "elif", "while", "until", "exec", "command",
                                              "nice", "env", "sudo", "$sudo")):
                    words = words[1:]
                if words:
                    commands.append(words)
        return commands

    def check_command(self, words, where, functions):
        word = words[0]
        if word in SHELL_WORDS or word in functions or not re.match(r"^[a-z][\w.+-]*$", word):
            return  # builtins, functions, variables, paths of this repository
        path = shutil.which(word, path="/usr/bin:/bin:/usr/sbin:/sbin")
        if path is None:
            self.checked["command"] += 1
            self.problem("command %s (%s): not found in /usr/bin, /bin, /usr/sbin or /sbin" % (word, where))
            return
        self.expect_file("command " + word, where, path)
        if word in COMMAND_KEYS:
            self.used[COMMAND_KEYS[word]].add(where)
        args = [w.strip("\"'") for w in words[1:]]
        if word == "rosrun" and len(args) >= 2 and not args[0].startswith("$"):
            self.ros_executable(args[0], args[1], where)
        if word in ("roslaunch", "rostest") and len(args) >= 2 and not args[0].startswith(("$", "-")):
            self.ros_package(args[0], where)

    def ros_package(self, name, where):
        if name == "aloam_nodelet":
            return
        self.used[name].add(where)
        manifest = "/usr/share/%s/package.xml" % name
        if not os.path.exists(manifest):
            self.checked["ros"] += 1
            self.problem("ROS package %s (%s): %s missing" % (name, where, manifest))
            return
        self.expect_file("ros package " + name, where, manifest)

    def ros_executable(self, package, executable, where):
        if package == "aloam_nodelet":
            return
        candidates = glob.glob("/usr/lib/%s/%s" % (package, executable))
        candidates += glob.glob("/usr/lib/*/%s/%s" % (package, executable))
        candidates += glob.glob("/usr/share/%s/**/%s" % (package, executable), recursive=True)
        candidates = [c for c in candidates if os.access(c, os.X_OK) and os.path.isfile(c)]
        if not candidates:
            self.checked["rosrun"] += 1
            self.problem("rosrun %s %s (%s): no such executable installed" % (package, executable, where))
            return
        self.expect_file("rosrun %s %s" % (package, executable), where, candidates[0])
        self.used[package].add(where)

    def commands(self):
        shell = {f: self.read(f) for f in self.shell_files()}
        functions = self.shell_functions(shell.values())
        for path, text in shell.items():
            for words in self.shell_commands(text):
                self.check_command(words, os.path.relpath(path, self.root), functions)
        # Python test nodes: subprocess calls with a literal program name.
        for path in self.python_files():
            text = self.read(path)
            for m in re.finditer(r"(?:subprocess\.\w+|Popen)\(\s*\[([^\]]*)", text):
                literal = re.findall(r"\"([^\"]*)\"|'([^']*)'", m.group(1))
                words = [a or b for a, b in literal]
                head = m.group(1).lstrip()
                if words and head.startswith(("\"", "'")):
                    self.check_command(words, os.path.relpath(path, self.root), functions)
        # README: shell code blocks, and inline code that starts with a ROS or catkin command.
        # The README and docs/: shell code blocks, and inline code that starts with a ROS or catkin command.
        for path in self.files([""], ["README.md"], recursive=False) + self.files(["docs"], [".md"]):
            text, where = self.read(path), os.path.relpath(path, self.root)
            for block in re.findall(r"```(?:bash|sh|shell)\n(.*?)```", text, re.S):
                for words in self.shell_commands(block):
                    self.check_command(words, where, functions)
            for span in re.findall(r"`([^`\n]+)`", text):
                words = span.split()
                if len(words) > 1 and re.match(r"^(ros\w+|catkin_\w+|dynparam|rviz|pcl_\w+|rqt\w*)$", words[0]):
                    self.check_command(words, where, functions)

    # ---- launch and rostest files --------------------------------------------------------------------
    def launch_files(self):
        files = self.files(["launch"], [".launch"], recursive=False) + self.files(["test"], [".test", ".launch"])
        for path in sorted(files):
            text = self.read(path)
            where = os.path.relpath(path, self.root)
            for pkg in set(re.findall(r"<(?:node|test)\b[^>]*\bpkg=\"([^\"$]+)\"", text, re.S)) | \
                    set(re.findall(r"\$\(find ([\w]+)\)", text)):
                self.ros_package(pkg, where)
            # Nodelets of other packages loaded by class name ("load pcl/CropBox manager").
            for cls in set(re.findall(r"\bload\s+([\w]+/[\w]+)", text)):
                if cls.startswith("aloam_nodelet/"):
                    continue
                declared = [f for f in glob.glob("/usr/share/*/**/*.xml", recursive=True)
                            if 'name="%s"' % cls in open(f, encoding="utf-8", errors="replace").read()]
                if not declared:
                    self.checked["nodelet"] += 1
                    self.problem("nodelet %s (%s): no installed plugin description declares it" % (cls, where))
                    continue
                self.expect_file("nodelet " + cls, where, declared[0])
                self.ros_package(declared[0].split("/")[3], where)

    # ---- CMake ---------------------------------------------------------------------------------------
    def cmake(self):
        files = self.files([""], ["CMakeLists.txt"], recursive=False) + self.files(["test"], ["/CMakeLists.txt"])
        for path in files:
            text = re.sub(r"#.*", "", self.read(path))
            where = os.path.relpath(path, self.root)
            for args in re.findall(r"find_package\s*\(([^)]*)\)", text, re.I):
                words = args.split()
                name, rest = words[0], words[1:]
                if name == "catkin" and "COMPONENTS" in rest:
                    for component in rest[rest.index("COMPONENTS") + 1:]:
                        self.cmake_package(component, where, catkin_package=True)
                self.cmake_package(name, where, catkin_package=False)

    def cmake_package(self, name, where, catkin_package):
        """find_package(name) needs a config file or find module from an allowed package."""
        patterns = ["%sConfig.cmake" % name, "%s-config.cmake" % name.lower(), "Find%s.cmake" % name]
        self.checked["cmake"] += 1
        for pattern in patterns:
            # Where several packages install the file, one that is allowed satisfies it.
            found_in = sorted(self.debian.named(pattern), key=lambda item: (item[1] not in self.allowed, item))
            for path, pkg in found_in:
                if os.path.exists(path):
                    if pkg in self.allowed:
                        if catkin_package:
                            self.ros_package(name, where)
                        elif name in CMAKE_KEYS:
                            self.used[CMAKE_KEYS[name]].add(where)
                        return
                    found = "%s from %s" % (path, pkg)
                    self.problem("find_package(%s) (%s): %s, which is not in ALOAM_DEBIAN_PACKAGES nor its "
                                 "dependencies" % (name, where, found))
                    return
        self.problem("find_package(%s) (%s): no %s installed" % (name, where, " or ".join(patterns)))

    # ---- package.xml --------------------------------------------------------------------------------
    def manifest(self):
        """package.xml declares every ROS package and system library used (rosdep keys), and nothing else."""
        import xml.etree.ElementTree as ET
        root = ET.parse(os.path.join(self.root, "package.xml")).getroot()
        declared = defaultdict(set)
        for element in root:
            if element.tag.endswith("depend"):
                declared[element.text.strip()].add(element.tag)
        # C++ includes: they must be declared for building.
        sources = self.files(["src", "include", "test"], CXX_SUFFIXES)
        build_keys = defaultdict(set)
        for path in sources:
            for top in re.findall(r"^#include\s*<(\w+)/", self.read(path), re.M):
                key = INCLUDE_KEYS.get(top, top if is_ros_package(top) else None)
                if key and key != "aloam_nodelet":
                    build_keys[key].add(os.path.relpath(path, self.root))
        for key, where in build_keys.items():
            self.used[key] |= where
            if not declared[key] & {"depend", "build_depend", "test_depend"}:
                self.problem("package.xml: %s is included by %s but not a build dependency"
                             % (key, ", ".join(sorted(where)[:2])))
        if re.search(r"add_(message|service)_files", self.read(os.path.join(self.root, "CMakeLists.txt"))):
            self.used["message_runtime"].add("CMakeLists.txt")
        self.used["catkin"].add("CMakeLists.txt")
        for key, where in sorted(self.used.items()):
            self.checked["package.xml"] += 1
            if key not in declared:
                self.problem("package.xml: %s is used (%s) but not declared" % (key, ", ".join(sorted(where)[:2])))
        for key in sorted(declared):
            if key not in self.used:
                self.problem("package.xml: %s is declared but nothing uses it" % key)

    def run(self):
        for pkg in self.not_installed:
            self.problem("listed package %s is not installed (run scripts/build.sh or scripts/test.sh)" % pkg)
        self.python_modules()
        self.commands()
        self.launch_files()
        self.cmake()
        self.manifest()
        counts = ", ".join("%d %s" % (n, what) for what, n in sorted(self.checked.items()))
        if self.problems:
            for text in sorted(set(self.problems)):
                print("missing dependency: " + text)
            print("dependency self-check FAILED (%d problems; checked %s). Add the Debian package that provides "
                  "each to ALOAM_DEBIAN_PACKAGES in scripts/common.sh (and its rosdep key to package.xml)."
                  % (len(set(self.problems)), counts))
            return 1
        print("dependency self-check passed: %s, all from ALOAM_DEBIAN_PACKAGES, its dependencies or the base "
              "system" % counts)
        return 0


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    if sys.argv[1] == "--provided":
        debian = Debian()
        sys.exit(0 if sys.argv[2] in debian.closure(sys.argv[3:]) | debian.closure(debian.base) else 1)
    try:
        sys.exit(Check(os.path.abspath(sys.argv[1]), sys.argv[2:]).run())
    except Exception:  # a crash is a failed check, said as such
        traceback.print_exc()
        print("dependency self-check FAILED: it crashed (traceback above), so nothing was proven")
        sys.exit(1)
