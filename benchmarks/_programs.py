"""Generated L-IRL programs for the benchmarks (deterministic: the same text every run)."""
from __future__ import annotations

import random


def large_program(lines: int = 10_000, seed: int = 1) -> str:
    """A valid program of about ``lines`` lines that mixes what real programs contain:
    moves with clauses, arithmetic, loops, conditionals, I/O, waits, procedure calls."""
    rng = random.Random(seed)
    head = [
        "program big;",
        'system_specification "lola15.spc";',
        "const PITCH := 120.5; ROWS := 4; COLS := 5;",
        "var i, j, n : integer;",
        "    x, y, z : real;",
        "    home : joint := joint(mainjoint(0, 0, 0, 0, 0, 0));",
        "    p : pose;",
        "    pts : array[1..20] of pose;",
        "procedure approach(target : pose; h : real);",
        "seq",
        "  move lin pose(pos(target.x, target.y, target.z + h), rpy(0, 180, 0)) speed := 200;",
        "endseq",
        "endprocedure;",
        "seq",
    ]
    body: list[str] = []
    while len(body) < lines - len(head) - 2:
        kind = rng.randrange(8)
        a = [rng.randint(-40, 40) for _ in range(6)]
        if kind == 0:
            body.append(f"  move ptp joint(mainjoint({', '.join(map(str, a))})) "
                        f"speed_ptp := 0.{rng.randint(1, 9)} acc_ptp := 0.{rng.randint(1, 9)};")
        elif kind == 1:
            body.append(f"  x := (x + {rng.randint(1, 99)}.5) * 2 - y / 3 + sin({rng.randint(0, 90)});")
        elif kind == 2:
            body += ["  for i := 1 to ROWS do",
                     "    for j := 1 to COLS do",
                     "      pts[(i - 1) * COLS + j] := pose(pos(500 + i * PITCH, j * PITCH, 300), rpy(0, 180, 0));",
                     "    endfor;",
                     "  endfor;"]
        elif kind == 3:
            body += [f"  if x > {rng.randint(0, 100)} and not in[{rng.randint(1, 16)}] then",
                     f"    out[{rng.randint(1, 16)}] := true;",
                     f"  elsif y < {rng.randint(0, 9)} then",
                     "    n := n + 1;",
                     "  else",
                     "    print \"cycle\", n;",
                     "  endif;"]
        elif kind == 4:
            body += ["  n := 0;", "  while n < 3 do", "    n := n + 1;", "  endwhile;"]
        elif kind == 5:
            body.append(f"  wait for in[{rng.randint(1, 16)}] timeout {rng.randint(1, 9)} sec;")
        elif kind == 6:
            body.append(f"  p := pose(pos({rng.randint(400, 900)}, {rng.randint(-300, 300)}, "
                        f"{rng.randint(200, 700)}), rpy(0, 180, {rng.randint(-90, 90)}));")
            body.append(f"  call approach(p, {rng.randint(10, 100)});")
        else:
            body.append(f"  home[{rng.randint(1, 6)}] := {rng.randint(-30, 30)}; wait 0.{rng.randint(1, 9)} sec;")
    return "\n".join(head + body + ["endseq", "endprogram;", ""])
