"""A safe parser for the expressions of a system file (mass matrix, guidance, potential).

The grammar is small and closed: numbers, names, ``+ - * / **``, parentheses and the
functions sin, cos, tan, exp, log, sqrt of one argument::

    expr  := term (('+' | '-') term)*
    term  := unary (('*' | '/') unary)*
    unary := ('+' | '-') unary | power
    power := atom ('**' unary)?             (right associative: -x**2 = -(x**2))
    atom  := NUMBER | NAME | FUNC '(' expr ')' | '(' expr ')'

NAME is a coordinate, a constant or ``pi``. The text is tokenized and parsed here by
recursive descent, and the sympy expression is
built node by node from :class:`sympy.Symbol` objects that this module creates: nothing of
the file is ever evaluated as Python (no ``eval``, no ``sympy.parse_expr``). Numbers are
folded in floating point, so that ``9**9**9`` costs nothing and a result that is not a
finite real number (``1/0``, ``log(-1)``, ``1e999``) is refused. Text length and nesting
depth are bounded.
"""

from __future__ import annotations

import enum
import math
import re
from typing import Mapping

from gyro_rotor.errors import did_you_mean, SystemFileError
import sympy

__all__ = ['parse_expression', 'FUNCTIONS', 'MAX_LENGTH', 'MAX_DEPTH', 'TokenKind']

#: the functions an expression may call (one argument each)
FUNCTIONS = {'sin': sympy.sin, 'cos': sympy.cos, 'tan': sympy.tan, 'exp': sympy.exp,
             'log': sympy.log, 'sqrt': sympy.sqrt}
#: longest expression text accepted
MAX_LENGTH = 4000
#: deepest nesting of parentheses, unary signs and powers
MAX_DEPTH = 60
#: integer exponents up to this size stay exact (x**2 stays x*x in the generated code)
_MAX_INT_EXPONENT = 64

#: ASCII only: ``\d`` would take any Unicode digit (``x**\uff12`` read as x**2)
_TOKEN = re.compile(r'[ \t\r\n]*(?:(?P<num>(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)'
                    r'|(?P<name>[A-Za-z_][A-Za-z0-9_]*)|(?P<op>\*\*|[-+*/()]))', re.ASCII)


_SPACE = ' \t\r\n'


class TokenKind(enum.Enum):
    """Kinds of tokens of the expression grammar."""

    NUMBER = 'number'
    NAME = 'name'
    OP = 'operator'
    END = 'end'


class _Refusal(Exception):
    """Internal: a parse error at a column (turned into a SystemFileError by the caller)."""

    def __init__(self, column: int, message: str):
        super().__init__(message)
        self.column = column
        self.message = message


def _tokenize(text: str) -> list[tuple[TokenKind, str, int]]:
    tokens = []
    pos = 0
    while pos < len(text):
        rest = text[pos:].lstrip(_SPACE)
        if rest == '':
            break
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            col = len(text) - len(rest)
            ch = text[col]
            hint = " (powers are written '**')" if ch == '^' else ''
            raise _Refusal(col, f'unexpected character {ch!r}{hint}')
        kind = next(k for k in ('num', 'name', 'op') if m.group(k) is not None)
        start = m.start(kind)
        tokens.append(({'num': TokenKind.NUMBER, 'name': TokenKind.NAME,
                        'op': TokenKind.OP}[kind], m.group(kind), start))
        pos = m.end()
    tokens.append((TokenKind.END, '', len(text)))
    return tokens


def _number(value: float, column: int):
    if not math.isfinite(value):
        raise _Refusal(column, f'the number {value!r} is not finite')
    if value.is_integer() and abs(value) <= 2 ** 53:
        return sympy.Integer(int(value))
    return sympy.Float(value)


class _Parser:
    """Recursive descent over the token list (see module doc)."""

    def __init__(self, tokens, names: Mapping[str, sympy.Symbol]):
        self.tokens = tokens
        self.i = 0
        self.names = names
        self.depth = 0

    def peek(self):
        return self.tokens[self.i]

    def take(self):
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def expect(self, text: str):
        kind, value, col = self.take()
        if value != text or kind is not TokenKind.OP:
            found = f'{value!r}' if kind is not TokenKind.END else 'the end of the text'
            raise _Refusal(col, f"expected '{text}', found {found}")

    def nest(self, col: int):
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise _Refusal(col, f'nested more than {MAX_DEPTH} levels deep')

    def left_assoc(self, ops, operand):
        """Parse ``operand (op operand)*`` for the operators ``ops``, grouped from the left."""
        left = operand()
        while self.peek()[1] in ops and self.peek()[0] is TokenKind.OP:
            _, op, col = self.take()
            left = _combine(op, left, operand(), col)
        return left

    def expr(self):
        return self.left_assoc(('+', '-'), self.term)

    def term(self):
        return self.left_assoc(('*', '/'), self.unary)

    def unary(self):
        kind, value, col = self.peek()
        if kind is TokenKind.OP and value in ('+', '-'):
            self.take()
            self.nest(col)
            operand = self.unary()
            self.depth -= 1
            return _combine('*', sympy.Integer(-1), operand, col) if value == '-' else operand
        return self.power()

    def power(self):
        base = self.atom()
        kind, value, col = self.peek()
        if kind is TokenKind.OP and value == '**':
            self.take()
            self.nest(col)
            exponent = self.unary()
            self.depth -= 1
            return _combine('**', base, exponent, col)
        return base

    def atom(self):
        kind, value, col = self.take()
        if kind is TokenKind.NUMBER:
            return _number(float(value), col)
        if kind is TokenKind.NAME:
            if value in FUNCTIONS:
                self.expect('(')
                self.nest(col)
                arg = self.expr()
                self.depth -= 1
                self.expect(')')
                return _apply(value, arg, col)
            if value in self.names:
                return self.names[value]
            if value == 'pi':
                return sympy.pi
            hint = did_you_mean(value, list(self.names) + list(FUNCTIONS))
            raise _Refusal(col, f"unknown name '{value}'{hint}")
        if kind is TokenKind.OP and value == '(':
            self.nest(col)
            inner = self.expr()
            self.depth -= 1
            self.expect(')')
            return inner
        found = f'{value!r}' if kind is not TokenKind.END else 'the end of the text'
        raise _Refusal(col, f'expected a number, a name or (, found {found}')


def _finite(result, col: int, what: str):
    if result.has(sympy.zoo, sympy.nan, sympy.oo, -sympy.oo, sympy.I):
        raise _Refusal(col, f'{what} is not a finite real number')
    if not result.free_symbols:         # a constant such as sqrt(pi - 4): its value
        try:
            v = complex(result.evalf())
        except (TypeError, ValueError, OverflowError):
            raise _Refusal(col, f'{what} is not a finite real number') from None
        if v.imag != 0 or not math.isfinite(v.real):
            raise _Refusal(col, f'{what} is not a finite real number')
    return result


def _combine(op: str, a, b, col: int):
    if a.is_Number and b.is_Number:
        x, y = float(a), float(b)
        try:
            if op == '+':
                v = x + y
            elif op == '-':
                v = x - y
            elif op == '*':
                v = x * y
            elif op == '/':
                v = x / y
            else:
                v = x ** y
        except (ZeroDivisionError, OverflowError):
            raise _Refusal(col, f"'{op}' of {x!r} and {y!r} is not a finite real "
                                f'number') from None
        if isinstance(v, complex) or not math.isfinite(v):
            raise _Refusal(col, f"'{op}' of {x!r} and {y!r} is not a finite real number")
        return _number(v, col)
    if op == '+':
        return _finite(a + b, col, 'the sum')
    if op == '-':
        return _finite(a - b, col, 'the difference')
    if op == '*':
        return _finite(a * b, col, 'the product')
    if op == '/':
        if b == 0:
            raise _Refusal(col, 'division by zero')
        return _finite(a / b, col, 'the quotient')
    if b.is_Number and not (b.is_Integer and abs(int(b)) <= _MAX_INT_EXPONENT):
        b = sympy.Float(float(b))
    return _finite(a ** b, col, 'the power')


def _apply(name: str, arg, col: int):
    if arg.is_Number:
        x = float(arg)
        try:
            v = {'sin': math.sin, 'cos': math.cos, 'tan': math.tan, 'exp': math.exp,
                 'log': math.log, 'sqrt': math.sqrt}[name](x)
        except (ValueError, OverflowError):
            raise _Refusal(col, f'{name}({x!r}) is not a finite real number') from None
        return _number(v, col)
    return _finite(FUNCTIONS[name](arg), col, f'{name}(...)')


def parse_expression(text, names: Mapping[str, sympy.Symbol], *, where: str):
    """Parse one expression of a system file into a sympy expression.

    Parameters
    ----------
    text : str or int or float
        The expression text (a YAML number is accepted as it is).
    names : mapping
        The names an expression may use (coordinates and constants) and their symbols.
    where : str
        File and key, for the error message (e.g. ``"system file f.yaml: mass_matrix[0][1]"``).

    Raises
    ------
    SystemFileError
        The text is not an expression of the grammar; the message names ``where``, the
        column and the offending text.
    """
    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise SystemFileError(f'{where}: expected an expression (text or number), got '
                              f'{text!r}')
    if not isinstance(text, str):
        if not math.isfinite(float(text)):
            raise SystemFileError(f'{where}: the number {text!r} is not finite')
        return _number(float(text), 0)
    if len(text) > MAX_LENGTH:
        raise SystemFileError(f'{where}: expression longer than {MAX_LENGTH} characters')
    if not text.strip():
        raise SystemFileError(f'{where}: empty expression')
    try:
        parser = _Parser(_tokenize(text), names)
        result = parser.expr()
        kind, value, col = parser.peek()
        if kind is not TokenKind.END:
            raise _Refusal(col, f'unexpected {value!r} after a complete expression')
    except _Refusal as err:
        snippet = text[max(0, err.column - 20):err.column + 20]
        from gyro_rotor.core.yamlio import short
        raise SystemFileError(f'{where}: {err.message} at column {err.column + 1} of '
                              f'{short(text, 100)} (near {snippet!r})') from None
    except RecursionError:  # pragma: no cover - bounded by MAX_DEPTH
        raise SystemFileError(f'{where}: expression nested too deeply') from None
    return result
