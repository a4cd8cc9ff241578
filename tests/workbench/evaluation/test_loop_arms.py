"""``evaluate loop``'s arms are the page's queue policy with one lever changed, not flags threaded through layers."""

from dataclasses import fields

import labeling
from workbench.cycle import SESSION_POLICY
from workbench.evaluation.loop_arms import ABLATIONS, LoopArm, loop_arm


def test_each_ablation_changes_one_lever_of_the_pages_queue() -> None:
    plain = LoopArm()
    for name, arm in ABLATIONS.items():
        changed = [f.name for f in fields(LoopArm) if getattr(arm, f.name) != getattr(plain, f.name)]
        assert len(changed) == 1, (name, changed)
        if changed == ["policy"]:
            levers = [
                f.name
                for f in fields(labeling.QueuePolicy)
                if getattr(arm.policy, f.name) != getattr(SESSION_POLICY, f.name)
            ]
            assert len(levers) == 1, (name, levers)


def test_a_strategy_is_the_sessions_policy_with_that_strategy() -> None:
    for strategy in labeling.STRATEGIES:
        arm = loop_arm(strategy)
        assert arm.policy.strategy == strategy and arm.votes and arm.policy.main_answer == SESSION_POLICY.main_answer
    assert loop_arm("combined-no-wrong-first").policy.wrong_first is False
    assert loop_arm("combined-no-votes").votes is False
