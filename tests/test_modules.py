"""Modules (issue 17, item 6): a program imports files of constants, variables,
procedures and functions; the object code stays one self-contained, verified program
whose line table says which file each statement came from; diagnostics and run-time
errors name the module's file and line."""
from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import pytest

from compiler.driver import compile_file
from compiler.objcode import ObjectCodeError, decode, encode, verify

from conftest import ROOT, SPEC_PATH as SPEC, run_cli


def write(directory: Path, name: str, text: str) -> Path:
    path = directory / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def program(directory: Path, body: str, imports: str, decls: str = "") -> Path:
    shutil.copy(SPEC, directory / "lola15.spc")
    return write(directory, "main.irl", f'program main;\nsystem_specification "lola15.spc";\n{imports}{decls}'
                                        f"seq\n{body}endseq\nendprogram;\n")


def test_the_pallet_program_is_made_with_its_module_and_says_where_each_line_came_from():
    result = compile_file(ROOT / "programs" / "pallet_frame.irl")
    assert result.ok, result.diagnostics
    p = result.program
    assert p.files == ("lib/pallet_cell.irl",)
    verify(p)
    assert decode(encode(p)) == p
    function = next(proc for proc in p.procedures if proc.name == "place_of")
    assert p.file_at(function.entry) == "lib/pallet_cell.irl" and p.file_at(0) == ""
    code, out, _ = run_cli("dis", ROOT / "programs" / "pallet_frame.irl")
    assert code == 0 and "modules        lib/pallet_cell.irl" in out
    assert "; lib/pallet_cell.irl:" in out and "return pallet * pose(" in out


def test_a_module_imported_twice_is_loaded_once_and_its_declarations_come_first(tmp_path):
    write(tmp_path, "lib/base.irl", "module base;\nconst\n  lift := 100.0;\nendmodule;\n")
    write(tmp_path, "lib/a.irl", 'module a;\nimport "base.irl";\nfunction up(z : real) : real;\nseq\n'
                                 "  return z + lift;\nendseq\nendfunction;\nendmodule;\n")
    write(tmp_path, "lib/b.irl", 'module b;\nimport "base.irl";\nvar count : integer := 2;\nendmodule;\n')
    main_file = program(tmp_path, "  print up(1), \" \", count;\n", 'import "lib/a.irl";\nimport "lib/b.irl";\n')
    result = compile_file(main_file)
    assert result.ok, result.diagnostics
    assert result.program.files == ("lib/base.irl", "lib/a.irl", "lib/b.irl")
    code, out, err = run_cli("run", main_file)
    assert code == 0 and "101 2" in out, out + err


@pytest.mark.parametrize("files, imports, words, where", [
    ({}, 'import "lib/missing.irl";\n', "cannot read module 'lib/missing.irl': no such file", "main.irl:3"),
    ({}, 'import "/dev/zero";\n', "cannot read module '/dev/zero': not a file", "main.irl:3"),
    ({}, 'import "a\x00b.irl";\n', "the file name contains a NUL byte", "main.irl:3"),
    ({}, 'import "' + "y" * 300 + '.irl";\n', "file name too long", "main.irl:3"),
    ({"lib/m.irl": "module m;\nprocedure p;\nseq\n  print secret;\nendseq\nendprocedure;\nendmodule;\n"},
     'import "lib/m.irl";\nconst\n  secret := 1;\n', "'secret' is declared in", "m.irl:4"),
    ({"lib/m.irl": "module m;\nconst\n  k := 1;\nendmodule;\n"}, 'import "lib/m.irl";\nfunction k : integer;\nseq\n'
     "  return 2;\nendseq\nendfunction;\n", "the first declaration is at line 3 of", "main.irl:4"),
    ({"lib/m.irl": "module m;\nconst\n  k := 1 + true;\nendmodule;\n"}, 'import "lib/m.irl";\n',
     "'+' needs two numbers", "m.irl:3"),
    ({"lib/m.irl": "module m;\nconst\n  k := 1;\nendmodule;\n"}, 'import "lib/m.irl";\nconst\n  k := 2;\n',
     "the first declaration is at line 3 of", "main.irl:5"),
    ({"a.irl": 'module a;\nimport "b.irl";\nendmodule;\n', "b.irl": 'module b;\nimport "a.irl";\nendmodule;\n'},
     'import "a.irl";\n', "the imports go round in a circle (main.irl -> a.irl -> b.irl -> a.irl)", "b.irl:2"),
    ({"a.irl": 'module a;\nimport "main.irl";\nendmodule;\n'}, 'import "a.irl";\n', "'main.irl' is the program",
     "a.irl:2"),
    ({"other.irl": "program other;\nseq\nendseq\nendprogram;\n"}, 'import "other.irl";\n', "is a program, not a module",
     "main.irl:3"),
    ({"lib/m.irl": "module m;\nconst\n  k := ;\nendmodule;\n"}, 'import "lib/m.irl";\n', "unexpected ';'", "m.irl:3"),
])
def test_module_errors_name_their_file_and_line(tmp_path, files, imports, words, where):
    for name, text in files.items():
        write(tmp_path, name, text)
    main_file = program(tmp_path, "  print 1;\n", imports)
    code, out, err = run_cli("check", main_file)
    assert code != 0 and words in err, err
    assert f"{where}:" in err, err


def test_a_module_is_not_compiled_by_itself(tmp_path):
    module = write(tmp_path, "m.irl", "module m;\nconst\n  k := 1;\nendmodule;\n")
    code, _out, err = run_cli("check", module, "--spec", SPEC)
    assert code != 0 and "'m' is a module: it is not compiled or run by itself" in err


def test_a_run_time_error_in_a_module_names_the_module(tmp_path):
    write(tmp_path, "lib/m.irl", "module m;\nfunction ratio(a, b : integer) : integer;\nseq\n  return a div b;\n"
                                 "endseq\nendfunction;\nendmodule;\n")
    main_file = program(tmp_path, "  n := 0;\n  print ratio(1, n);\n", 'import "lib/m.irl";\n',
                        "var n : integer;\n")
    code, out, err = run_cli("run", main_file)
    assert code != 0 and "program error at lib/m.irl line 4: division by zero (div)" in out + err, out + err


def test_the_decoder_refuses_a_malformed_file_table():
    result = compile_file(ROOT / "programs" / "pallet_frame.irl")
    good = result.program
    for bad in (dataclasses.replace(good, line_files=good.line_files[:-1]),
                dataclasses.replace(good, line_files=(9,) * len(good.line_files)),
                dataclasses.replace(good, files=("",))):
        with pytest.raises(ObjectCodeError, match="files"):
            decode(encode(bad))


def test_a_diagnostic_in_a_module_shows_the_modules_line(tmp_path):
    write(tmp_path, "lib/m.irl", "module m;\nconst\n  k := 1;\nvar v : integer := \"text\";\nendmodule;\n")
    main_file = program(tmp_path, "  print k;\n", 'import "lib/m.irl";\n')
    code, _out, err = run_cli("check", main_file)
    assert code != 0 and "m.irl:4:20: error: cannot initialise an integer with a string" in err
    assert 'var v : integer := "text";' in err, err  # the module's line, not the program's line 4


def test_a_name_declared_twice_in_one_file_is_blamed_on_the_later_declaration(tmp_path):
    main_file = program(tmp_path, "  print c;\n", "", "const\n  c := 1;\nprocedure c;\nseq\nendseq\nendprocedure;\n")
    code, _out, err = run_cli("check", main_file)
    assert "main.irl:5:11: error: 'c' is already declared" in err and "first declaration is at line 4" in err, err
