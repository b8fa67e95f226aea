"""The benches' -k option: values typed as the CLI's -k types them, and a pair that does not read refused at
the command line, naming the pair (before any run or worker starts)."""

import argparse

import pytest

from devkit.kwarg_option import add_kwarg_option, kwargs_from


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bench")
    add_kwarg_option(parser)
    return parser


def test_values_arrive_typed_and_a_later_pair_wins():
    args = _parser().parse_args(
        ["-k", "delta_coeff=0.1", "-k", "ee_action_type=true", "-k", "engine=mujoco", "-k", "delta_coeff=0.2"]
    )
    assert kwargs_from(args.kwarg) == {"delta_coeff": 0.2, "ee_action_type": True, "engine": "mujoco"}


def test_a_quoted_override_list_holding_brackets_reads():
    args = _parser().parse_args(["-k", 'overrides=["workspace.min=[-0.3, -0.85, 0.827]"]'])
    assert kwargs_from(args.kwarg) == {"overrides": ["workspace.min=[-0.3, -0.85, 0.827]"]}


@pytest.mark.parametrize(
    "pair, words",
    [
        ("overrides=[workspace.min=[-0.30,-0.85,0.827]]", "not valid YAML"),
        ("engine", "write name=value"),
        ("=mujoco", "write name=value"),
    ],
)
def test_a_pair_that_does_not_read_is_refused_naming_it(pair, words, capsys):
    with pytest.raises(SystemExit) as exited:
        _parser().parse_args(["-k", pair])
    assert exited.value.code == 2
    message = capsys.readouterr().err
    assert repr(pair) in message and words in message
