"""The offline half of irl: L-IRL source -> checked program -> object code.

Importing this package is cheap: the parser (Lark) is loaded only by the modules that
parse (``compiler.syntax`` and what uses it), so the runtime can load object code with
``compiler.objcode`` alone.
"""
