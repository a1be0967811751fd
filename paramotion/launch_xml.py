"""Read ROS 2 XML launch files (the ``ros2 launch`` format) into plain node descriptions.

The ``launch``/``launch_ros`` packages are not installable here, so this module interprets the
subset of their XML frontend that paramotion's launch files use, with the same meaning:

- ``<launch>`` holding ``<arg name default description>`` (with ``<choice value>`` children),
  ``<let name value>``, ``<group scoped>`` and ``<node>``; every action takes ``if``/``unless``;
- ``<node pkg exec name namespace output respawn respawn_delay args ros_args>`` with
  ``<param name value [value-sep]>``, ``<remap from to>`` and ``<env name value>`` children;
- substitutions ``$(var N)``, ``$(env N [default])``, ``$(optenv N [default])``,
  ``$(dirname)``, ``$(filename)``, ``$(find-pkg-share P)``, ``$(find-pkg-prefix P)``,
  ``$(equals A B)``, ``$(not-equals A B)`` and ``$(eval EXPR)`` (a safe Python expression
  subset: literals, arithmetic, comparisons, ``and``/``or``/``not``, ``x if c else y``,
  ``min``/``max``/``abs``/``round``/``int``/``float``/``str`` and ``math`` functions).

Parameter values are typed as ``ros2 launch`` types them (YAML: ``2.0`` is a double, ``1`` an
integer, ``true`` a bool, ``[a, b]`` a list, anything else a string). Anything outside the
subset (an unknown tag or attribute, an undefined argument, a bad condition) is refused with
one line naming the file, the line and what is wrong, never silently ignored.

No rclpy here: the process launcher (:mod:`paramotion.launch`) and the one-process scenario
runners both start from :func:`load`.
"""
import ast
import math
import os
import re
import sys
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.parsers import expat

import yaml

from paramotion import yamlfile
from paramotion.errors import UserError

PACKAGE = 'paramotion'
#: A parameter value as ``ros2 launch`` types it (see :func:`typed_value`).
ParamValue = bool | int | float | str | list[bool] | list[int] | list[float] | list[str]
#: Attribute text split by :func:`parse_text`: literal strings and ``(name, arguments)``
#: substitutions, each argument a list of such parts.
Part = str | tuple[str, list[list[Any]]]
_REPO = Path(__file__).resolve().parents[1]


class LaunchError(UserError):
    """A launch file or launch argument the interpreter refuses (one line)."""


@dataclass
class NodeAction:
    """One ``<node>``: what ``ros2 launch`` would start, with substitutions resolved."""

    package: str
    executable: str
    name: str = ''
    namespace: str = ''
    params: dict[str, ParamValue] = field(default_factory=dict)
    remaps: list[tuple[str, str]] = field(default_factory=list)
    env: dict[str, str] = field(default_factory=dict)
    args: list[str] = field(default_factory=list)
    ros_args: list[str] = field(default_factory=list)
    output: str = 'log'
    respawn: bool = False
    respawn_delay: float = 0.0
    where: str = ''

    @property
    def label(self) -> str:
        """Node name if given, else the executable (how logs and errors refer to it)."""
        return self.name or self.executable


@dataclass
class ArgDecl:
    """One ``<arg>`` declaration."""

    name: str
    default: str | None = None      # raw (unsubstituted) default text, None if required
    description: str = ''
    choices: tuple[str, ...] = ()


@dataclass
class LaunchDescription:
    """A launch file read with given arguments: its declared arguments, their final values
    and the nodes to start (after ``if``/``unless``)."""

    path: Path
    args: dict[str, ArgDecl]
    values: dict[str, str]
    nodes: list[NodeAction]

    def node(self, name: str) -> NodeAction:
        """The node called ``name`` (node name or executable)."""
        for n in self.nodes:
            if n.label == name:
                return n
        raise KeyError(name)


# ----------------------------------------------------------------------------- files
def share_directory(package: str) -> str:
    """``$(find-pkg-share PACKAGE)``: the package's installed share directory.

    Looked up in the ament index (``AMENT_PREFIX_PATH``), then in this Python's prefix (a pip
    install puts ``data_files`` there); for paramotion itself in an editable install, the
    source tree, which has the same layout (``package.xml``, ``launch/``).
    """
    prefix = prefix_directory(package)
    return str(Path(prefix) / 'share' / package) if prefix != str(_REPO) else str(_REPO)


def prefix_directory(package: str) -> str:
    """``$(find-pkg-prefix PACKAGE)``: the install prefix holding the package."""
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix and (Path(prefix) / 'share' / 'ament_index' / 'resource_index' / 'packages'
                       / package).is_file():
            return prefix
    if (Path(sys.prefix) / 'share' / package / 'package.xml').is_file():
        return sys.prefix
    if package == PACKAGE and (_REPO / 'package.xml').is_file():
        return str(_REPO)
    raise LaunchError(f"package '{package}' not found (not in AMENT_PREFIX_PATH, not "
                      f'installed under {sys.prefix}/share)')


def launch_directories() -> list[Path]:
    """Where ``paramotion launch NAME`` looks for NAME.launch.xml, in order."""
    dirs = []
    try:
        dirs.append(Path(share_directory(PACKAGE)) / 'launch')
    except LaunchError:
        pass
    if _REPO / 'launch' not in dirs:
        dirs.append(_REPO / 'launch')
    return dirs


def find_launch_file(spec: str) -> Path:
    """A launch file from a path, a file name or a short name (``coverage``)."""
    path = Path(spec)
    if path.suffix == '.xml' and path.exists():
        return path
    names = [spec] if spec.endswith('.xml') else [f'{spec}.launch.xml', f'{spec}.xml']
    for d in launch_directories():
        for n in names:
            if (d / n).is_file():
                return d / n
    known = sorted({p.name for d in launch_directories() if d.is_dir()
                    for p in d.glob('*.launch.xml')})
    raise LaunchError(f"launch file '{spec}' not found (known: {', '.join(known)})")


def parse_cli_args(items: Iterable[str]) -> dict[str, str]:
    """``['name:=value', ...]`` (``ros2 launch`` argument syntax) into a dict."""
    out = {}
    for item in items:
        name, sep, value = item.partition(':=')
        if not sep or not re.fullmatch(r'[A-Za-z_][A-Za-z0-9_]*', name):
            raise LaunchError(f'launch argument {item!r}: expected name:=value')
        out[name] = value
    return out


def arg_text(value: object) -> str:
    """A Python value as launch-argument text (what one would type after ``name:=``)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        if math.isnan(value):
            return '.nan'
        if math.isinf(value):
            return '.inf' if value > 0 else '-.inf'
        return repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(arg_text(v) for v in value) + ']'
    return str(value)


# ----------------------------------------------------------------------------- values
_FLOAT = re.compile(r'[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?')


def _fix_scalar(v):
    # PyYAML (YAML 1.1) reads 1e-05 as a string; ROS 2's parameter parser reads a double.
    if isinstance(v, str) and _FLOAT.fullmatch(v.strip()):
        return float(v)
    return v


def typed_value(text: str) -> ParamValue:
    """A parameter value from its text as ``ros2 launch`` types it (YAML scalars/lists)."""
    try:
        value = yamlfile.safe_load(text)
    except yaml.YAMLError:
        return text
    if value is None:
        return '' if text.strip() in ('', '~', 'null', 'Null', 'NULL') else text
    if isinstance(value, list):
        if any(isinstance(v, (list, dict)) or v is None for v in value):
            return text
        value = [_fix_scalar(v) for v in value]
        kinds = {type(v) for v in value}
        if kinds == {int, float}:
            value = [float(v) for v in value]
        elif len(kinds) > 1:
            return text
        return value
    if isinstance(value, (bool, int, float, str)):
        return _fix_scalar(value)
    return text


def to_bool(text: object, what: str) -> bool:
    """A condition value: true/false/1/0 (any case), as ``ros2 launch`` accepts."""
    t = str(text).strip().lower()
    if t in ('true', '1'):
        return True
    if t in ('false', '0'):
        return False
    raise LaunchError(f'{what}: {text!r} is not a boolean (true/false/1/0)')


# ----------------------------------------------------------------------------- eval
_SAFE_FUNCS = {'min': min, 'max': max, 'abs': abs, 'round': round, 'int': int,
               'float': float, 'str': str, 'bool': bool, 'len': len}
_SAFE_FUNCS.update({k: getattr(math, k) for k in dir(math) if not k.startswith('_')})
_BINOPS = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
           ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b,
           ast.FloorDiv: lambda a, b: a // b, ast.Mod: lambda a, b: a % b,
           ast.Pow: lambda a, b: a ** b}
_CMPOPS = {ast.Eq: lambda a, b: a == b, ast.NotEq: lambda a, b: a != b,
           ast.Lt: lambda a, b: a < b, ast.LtE: lambda a, b: a <= b,
           ast.Gt: lambda a, b: a > b, ast.GtE: lambda a, b: a >= b,
           ast.In: lambda a, b: a in b, ast.NotIn: lambda a, b: a not in b}


def safe_eval(expr: str) -> Any:
    """Evaluate the expression subset of ``$(eval ...)`` without Python's ``eval``."""
    def ev(n):
        if isinstance(n, ast.Expression):
            return ev(n.body)
        if isinstance(n, ast.Constant) and isinstance(n.value, (int, float, str, bool)):
            return n.value
        if isinstance(n, (ast.List, ast.Tuple)):
            return [ev(e) for e in n.elts]
        if isinstance(n, ast.Name):
            if n.id in ('True', 'False'):
                return n.id == 'True'
            if n.id in ('pi', 'e', 'inf', 'tau') and n.id in _SAFE_FUNCS:
                return _SAFE_FUNCS[n.id]
            raise ValueError(f'unknown name {n.id!r}')
        if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) \
                and n.value.id == 'math' and hasattr(math, n.attr):
            return getattr(math, n.attr)
        if isinstance(n, ast.UnaryOp):
            v = ev(n.operand)
            if isinstance(n.op, ast.Not):
                return not v
            if isinstance(n.op, ast.USub):
                return -v
            if isinstance(n.op, ast.UAdd):
                return +v
        if isinstance(n, ast.BinOp) and type(n.op) in _BINOPS:
            return _BINOPS[type(n.op)](ev(n.left), ev(n.right))
        if isinstance(n, ast.BoolOp):
            vals = (ev(v) for v in n.values)
            return all(vals) if isinstance(n.op, ast.And) else any(vals)
        if isinstance(n, ast.Compare):
            left = ev(n.left)
            for op, comp in zip(n.ops, n.comparators):
                right = ev(comp)
                if type(op) not in _CMPOPS or not _CMPOPS[type(op)](left, right):
                    return False
                left = right
            return True
        if isinstance(n, ast.IfExp):
            return ev(n.body) if ev(n.test) else ev(n.orelse)
        if isinstance(n, ast.Call) and not n.keywords:
            func = ev(n.func) if isinstance(n.func, ast.Attribute) else \
                _SAFE_FUNCS.get(getattr(n.func, 'id', None))
            if callable(func):
                return func(*[ev(a) for a in n.args])
        raise ValueError(f'unsupported expression {ast.dump(n)[:60]}')
    return ev(ast.parse(expr.strip(), mode='eval'))


def _eval_text(value):
    if isinstance(value, bool):
        return 'true' if value else 'false'
    return str(value)


# ----------------------------------------------------------------------------- substitutions
def _split_args(text, i, what):
    """Parse the inside of ``$(...)`` from ``text[i:]``: returns (name, [arg parts], end)."""
    m = re.compile(r'\s*([A-Za-z][A-Za-z0-9_-]*)').match(text, i)
    if not m:
        raise LaunchError(f'{what}: bad substitution near {text[i - 2:i + 20]!r}')
    name, i = m.group(1), m.end()
    args, cur, quote = [], None, None
    while True:
        if i >= len(text):
            raise LaunchError(f'{what}: unclosed substitution $({name} ...')
        c = text[i]
        if quote is None and c == ')':
            if cur is not None:
                args.append(cur)
            return name, args, i + 1
        if quote is None and c.isspace():
            if cur is not None:
                args.append(cur)
                cur = None
            i += 1
            continue
        if cur is None:
            cur = []
        if c in '\'"' and (quote is None or quote == c):
            quote = None if quote == c else c
            i += 1
            continue
        if text.startswith('$(', i):
            sub, end = _parse_subst(text, i + 2, what)
            cur.append(sub)
            i = end
            continue
        if cur and isinstance(cur[-1], str):
            cur[-1] += c
        else:
            cur.append(c)
        i += 1


def _parse_subst(text, i, what):
    name, args, end = _split_args(text, i, what)
    return (name, args), end


def parse_text(text: str, what: str) -> list[Part]:
    """Split attribute text into literal strings and ``(name, args)`` substitutions."""
    parts, i, lit = [], 0, ''
    while i < len(text):
        if text.startswith('$(', i):
            if lit:
                parts.append(lit)
                lit = ''
            sub, i = _parse_subst(text, i + 2, what)
            parts.append(sub)
        else:
            lit += text[i]
            i += 1
    if lit:
        parts.append(lit)
    return parts


def _normal(v):
    t = v.strip()
    if t.lower() in ('true', 'false'):
        return t.lower() == 'true'
    try:
        return float(t)
    except ValueError:
        return t


class _Context:
    """Launch configurations (argument and ``let`` values) and the current file."""

    def __init__(self, path, values):
        self.path = Path(path).resolve()
        self.values = dict(values)

    def substitute(self, text, what):
        return self._resolve(parse_text(text, what), what)

    def _resolve(self, parts, what):
        return ''.join(p if isinstance(p, str) else self._apply(p, what) for p in parts)

    def _apply(self, sub, what):
        name, raw_args = sub
        args = [self._resolve(a, what) for a in raw_args]

        def need(lo, hi):
            if not lo <= len(args) <= hi:
                raise LaunchError(f'{what}: $({name}) takes {lo}'
                                  + (f'-{hi}' if hi != lo else '') + f' argument(s), got '
                                  f'{len(args)}')
        if name == 'var':
            need(1, 1)
            if args[0] not in self.values:
                raise LaunchError(f'{what}: $(var {args[0]}): no such launch argument')
            return self.values[args[0]]
        if name in ('env', 'optenv'):
            need(1, 2)
            if args[0] in os.environ:
                return os.environ[args[0]]
            if len(args) == 2:
                return args[1]
            if name == 'optenv':
                return ''
            raise LaunchError(f'{what}: $(env {args[0]}): environment variable not set')
        if name == 'dirname':
            need(0, 0)
            return str(self.path.parent)
        if name == 'filename':
            need(0, 0)
            return self.path.name
        if name == 'find-pkg-share':
            need(1, 1)
            return share_directory(args[0])
        if name == 'find-pkg-prefix':
            need(1, 1)
            return prefix_directory(args[0])
        if name in ('equals', 'not-equals'):
            need(1, 2)
            a, b = args[0], args[1] if len(args) == 2 else ''
            same = _normal(a) == _normal(b)
            return _eval_text(same if name == 'equals' else not same)
        if name == 'eval':
            need(1, 1)
            try:
                return _eval_text(safe_eval(args[0]))
            except Exception as exc:
                raise LaunchError(f'{what}: $(eval {args[0]!r}): {exc}') from None
        raise LaunchError(f'{what}: unknown substitution $({name} ...) (supported: var, env, '
                          'optenv, dirname, filename, find-pkg-share, find-pkg-prefix, '
                          'equals, not-equals, eval)')


# ----------------------------------------------------------------------------- parsing
_ACTION_ATTRS = {'if', 'unless'}
_TAGS = {
    'arg': {'name', 'default', 'description'},
    'let': {'name', 'value'} | _ACTION_ATTRS,
    'group': {'scoped', 'forwarding'} | _ACTION_ATTRS,
    'node': {'pkg', 'exec', 'name', 'namespace', 'output', 'respawn', 'respawn_delay',
             'args', 'ros_args'} | _ACTION_ATTRS,
}
_NODE_CHILDREN = {'param': {'name', 'value', 'value-sep'}, 'remap': {'from', 'to'},
                  'env': {'name', 'value'}}


def _read_xml(path):
    """Parse ``path`` keeping each element's line number; one-line error on bad XML."""
    lines, stack, roots = {}, [], []
    parser = expat.ParserCreate()

    def start(tag, attrs):
        el = ET.Element(tag, attrs)
        lines[el] = parser.CurrentLineNumber
        (stack[-1].append(el) if stack else roots.append(el))
        stack.append(el)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    try:
        parser.Parse(Path(path).read_bytes(), True)
    except expat.ExpatError as exc:
        raise LaunchError(f'{path}:{exc.lineno}: not well-formed XML: '
                          f'{expat.ErrorString(exc.code)}') from None
    except OSError as exc:
        raise LaunchError(f'{path}: cannot read: {exc.strerror}') from None
    return roots[0], lines


class _Reader:
    def __init__(self, path, cli_values):
        self.path = Path(path)
        self.root, self.lines = _read_xml(self.path)
        self.cli = dict(cli_values)
        self.ctx = _Context(self.path, {})
        self.decls = {}
        self.nodes = []

    def where(self, el):
        return f'{self.path}:{self.lines.get(el, 0)}'

    def check_attrs(self, el, allowed):
        for key in el.attrib:
            if key not in allowed:
                raise LaunchError(f"{self.where(el)}: <{el.tag}> has unknown attribute '{key}' "
                                  f"(allowed: {', '.join(sorted(allowed))})")

    def attr(self, el, key, required=False, default=None):
        if key not in el.attrib:
            if required:
                raise LaunchError(f"{self.where(el)}: <{el.tag}> needs attribute '{key}'")
            return default
        return self.ctx.substitute(el.attrib[key], f'{self.where(el)}: <{el.tag} {key}>')

    def enabled(self, el):
        what = self.where(el)
        if 'if' in el.attrib and not to_bool(self.attr(el, 'if'), f'{what}: if'):
            return False
        if 'unless' in el.attrib and to_bool(self.attr(el, 'unless'), f'{what}: unless'):
            return False
        return True

    def read(self):
        if self.root.tag != 'launch':
            raise LaunchError(f'{self.where(self.root)}: root element is <{self.root.tag}>, '
                              'expected <launch>')
        self.check_attrs(self.root, {'version'})
        self.actions(self.root)
        unknown = sorted(set(self.cli) - set(self.decls))
        if unknown:
            raise LaunchError(f"{self.path}: unknown launch argument '{unknown[0]}' "
                              f"(declared: {', '.join(self.decls) or 'none'})")
        return LaunchDescription(self.path, self.decls, dict(self.ctx.values), self.nodes)

    def actions(self, parent):
        for el in parent:
            if el.tag not in _TAGS:
                raise LaunchError(f'{self.where(el)}: unknown tag <{el.tag}> (supported: '
                                  f"{', '.join(sorted(_TAGS))})")
            self.check_attrs(el, _TAGS[el.tag])
            getattr(self, '_' + el.tag)(el)

    def _arg(self, el):
        name = el.attrib.get('name')
        if not name:
            raise LaunchError(f"{self.where(el)}: <arg> needs attribute 'name'")
        choices = []
        for child in el:
            if child.tag != 'choice':
                raise LaunchError(f'{self.where(child)}: unknown tag <{child.tag}> in <arg> '
                                  '(supported: choice)')
            self.check_attrs(child, {'value'})
            choices.append(self.attr(child, 'value', required=True))
        decl = ArgDecl(name, el.attrib.get('default'), el.attrib.get('description', ''),
                       tuple(choices))
        self.decls[name] = decl
        if name in self.cli:
            value = self.cli[name]
        elif decl.default is not None:
            value = self.attr(el, 'default')
        elif name in self.ctx.values:
            return
        else:
            raise LaunchError(f"{self.path}: launch argument '{name}' is required "
                              f'(pass {name}:=VALUE)')
        if choices and value not in choices:
            raise LaunchError(f"{self.path}: launch argument '{name}' = {value!r} not allowed; "
                              f"choices: {', '.join(choices)}")
        self.ctx.values[name] = value

    def _let(self, el):
        if self.enabled(el):
            self.ctx.values[self.attr(el, 'name', required=True)] = \
                self.attr(el, 'value', required=True)

    def _group(self, el):
        if not self.enabled(el):
            return
        scoped = to_bool(self.attr(el, 'scoped', default='true'), f'{self.where(el)}: scoped')
        saved = dict(self.ctx.values)
        self.actions(el)
        if scoped:
            self.ctx.values = saved

    def _node(self, el):
        if not self.enabled(el):
            return
        where = self.where(el)
        node = NodeAction(package=self.attr(el, 'pkg', required=True),
                          executable=self.attr(el, 'exec', required=True),
                          name=self.attr(el, 'name', default=''),
                          namespace=self.attr(el, 'namespace', default=''),
                          output=self.attr(el, 'output', default='log'), where=where)
        node.respawn = to_bool(self.attr(el, 'respawn', default='false'), f'{where}: respawn')
        delay = self.attr(el, 'respawn_delay', default='0.0')
        try:
            node.respawn_delay = float(delay)
            if not (node.respawn_delay >= 0 and math.isfinite(node.respawn_delay)):
                raise ValueError
        except ValueError:
            raise LaunchError(f'{where}: respawn_delay {delay!r}: expected seconds >= 0') \
                from None
        node.args = (self.attr(el, 'args', default='') or '').split()
        node.ros_args = (self.attr(el, 'ros_args', default='') or '').split()
        for child in el:
            if child.tag not in _NODE_CHILDREN:
                raise LaunchError(f'{self.where(child)}: unknown tag <{child.tag}> in <node> '
                                  f"(supported: {', '.join(sorted(_NODE_CHILDREN))})")
            self.check_attrs(child, _NODE_CHILDREN[child.tag])
            if child.tag == 'param':
                name = self.attr(child, 'name', required=True)
                text = self.attr(child, 'value', required=True)
                sep = child.attrib.get('value-sep')
                node.params[name] = ([typed_value(v) for v in text.split(sep)] if sep
                                     else typed_value(text))
            elif child.tag == 'remap':
                node.remaps.append((self.attr(child, 'from', required=True),
                                    self.attr(child, 'to', required=True)))
            else:
                node.env[self.attr(child, 'name', required=True)] = \
                    self.attr(child, 'value', required=True)
        self.nodes.append(node)


def recorded_topics(desc: LaunchDescription) -> list[str]:
    """The topics the launch file's recorder records (its ``topics`` parameter)."""
    for action in desc.nodes:
        if action.executable == 'bag_recorder':
            topics = action.params.get('topics', [])
            return [t for t in (topics if isinstance(topics, list) else [topics]) if t]
    raise LaunchError(f'{desc.path}: no bag_recorder node (pass record:=true)')


def load(spec: str | os.PathLike[str], launch_args: dict[str, object] | None = None
         ) -> LaunchDescription:
    """Read launch file ``spec`` (path or short name) with ``launch_args`` (name -> value;
    values may be Python values, converted with :func:`arg_text`)."""
    path = find_launch_file(str(spec))
    values = {k: arg_text(v) for k, v in (launch_args or {}).items()}
    return _Reader(path, values).read()


__all__ = ['ArgDecl', 'LaunchDescription', 'LaunchError', 'NodeAction', 'ParamValue', 'Part',
           'arg_text', 'find_launch_file', 'load', 'parse_cli_args', 'recorded_topics',
           'safe_eval', 'share_directory', 'typed_value']
