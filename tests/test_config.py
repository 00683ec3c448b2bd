"""genplan._config: the one check of the configuration dataclasses' fields (GanConfig, FlowConfig,
Seq2SeqConfig): a SettingsError naming the class, the field, what it must hold and the value."""

from dataclasses import dataclass, field

import pytest

from genplan._config import check_fields, integer, number, one_of, optional
from genplan.errors import SettingsError


@dataclass
class Config:
    count: object = 3
    seed: object = 0
    widths: object = (4, 4)
    rate: object = 0.1
    weight: object = 0.0
    fraction: object = 0.5
    offsets: object = field(default_factory=lambda: (-1.0, 2.0))
    loss: object = "bce"
    threads: object = None


RULES = {"count": integer(1), "seed": integer(0), "widths": integer(1, each=True), "rate": number(above=0),
         "weight": number(at_least=0), "fraction": number(at_least=0, at_most=1), "offsets": number(each=True),
         "loss": one_of(("bce", "wgan_gp")), "threads": optional(integer(1))}


def test_valid_values_pass() -> None:
    check_fields(Config(), RULES)
    check_fields(Config(threads=2, widths=[1], rate=3, fraction=1), RULES)  # ints are numbers; lists sequences


@pytest.mark.parametrize("changes, message", [
    ({"count": 0}, "Config.count must be a positive integer, got 0"),
    ({"count": True}, "Config.count must be a positive integer, got True"),  # a bool is no integer
    ({"count": 2.0}, "Config.count must be a positive integer, got 2.0"),
    ({"seed": -1}, "Config.seed must be a non-negative integer, got -1"),
    ({"widths": (4, 0)}, "Config.widths must hold positive integers, got (4, 0)"),
    ({"widths": 4}, "Config.widths must hold positive integers, got 4"),  # not a sequence
    ({"rate": 0.0}, "Config.rate must be a finite number > 0, got 0.0"),
    ({"rate": float("inf")}, "Config.rate must be a finite number > 0, got inf"),
    ({"rate": "0.1"}, "Config.rate must be a finite number > 0, got '0.1'"),
    ({"weight": -1e-9}, "Config.weight must be a finite number >= 0, got -1e-09"),
    ({"fraction": 1.5}, "Config.fraction must be a finite number in [0, 1], got 1.5"),
    ({"offsets": (0.0, float("nan"))}, "Config.offsets must hold finite numbers, got (0.0, nan)"),
    ({"loss": "mse"}, "Config.loss must be one of ['bce', 'wgan_gp'], got 'mse'"),
    ({"threads": 0}, "Config.threads must be None or a positive integer, got 0"),
])
def test_a_bad_value_names_the_class_the_field_and_the_rule(changes, message) -> None:
    with pytest.raises(SettingsError) as info:
        check_fields(Config(**changes), RULES)
    assert str(info.value) == message


def test_the_first_bad_field_in_the_rules_order_is_named() -> None:
    with pytest.raises(SettingsError, match=r"^Config\.seed"):
        check_fields(Config(seed=-1, loss="x"), RULES)
    with pytest.raises(SettingsError, match=r"^Config\.loss"):
        check_fields(Config(seed=-1, loss="x"), {"loss": RULES["loss"], "seed": RULES["seed"]})


def test_every_config_dataclass_checks_with_it() -> None:
    """GanConfig, FlowConfig and both Seq2SeqConfigs word their errors alike."""
    from genplan.pancake.config import Seq2SeqConfig as PancakeConfig
    from genplan.samplers.flow import FlowConfig
    from genplan.samplers.gan import GanConfig
    from genplan.seq2seq.config import Seq2SeqConfig

    box = ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    cases = [(lambda: GanConfig("panda", "hand", box, n_net=0), "GanConfig.n_net must be a positive integer, got 0"),
             (lambda: FlowConfig("panda", "hand", box, lr=-1.0), "FlowConfig.lr must be a finite number > 0, got -1.0"),
             (lambda: Seq2SeqConfig(network="gru"), "Seq2SeqConfig.network must be one of ['lstm', 'mlp'], got 'gru'"),
             (lambda: PancakeConfig(epochs=0), "Seq2SeqConfig.epochs must be a positive integer, got 0")]
    for make, message in cases:
        with pytest.raises(SettingsError) as info:
            make()
        assert str(info.value) == message
