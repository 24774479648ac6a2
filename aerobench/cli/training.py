"""`aerobench train` and `aerobench pi-init`: aerobench's own BC/PPO, and pi0/pi0.5 folders for lerobot-train."""

from __future__ import annotations

from pathlib import Path

from .common import Parser, UserError


def add_train(sub) -> None:
    from ..train.bc import BCConfig
    from ..train.common import add_config_arguments
    from ..train.perceive_act import PerceiveActConfig
    from ..train.ppo import PPOConfig

    p = sub.add_parser("train", help="train aerobench's own BC or PPO skill policies (checkpoints for --policy bc|ppo)")
    algos = p.add_subparsers(dest="algorithm", required=True, parser_class=Parser)
    bc = algos.add_parser("bc", help="behaviour cloning on the successful episodes of an exported dataset")
    add_config_arguments(bc, BCConfig, required=("dataset", "out"))
    bc.set_defaults(func=_run_train, config_cls=BCConfig)
    ppo = algos.add_parser("ppo", help="PPO on a skill env, from scratch or from a BC checkpoint (--init-bc DIR)")
    add_config_arguments(ppo, PPOConfig, required=("setting", "skill", "out"))
    ppo.set_defaults(func=_run_train, config_cls=PPOConfig)
    composed = algos.add_parser("perceive-act", help="a vision policy from a camera bc's auxiliary head (perception) "
                                "and a state controller reading the fields it estimates (--policy perceive_act)")
    add_config_arguments(composed, PerceiveActConfig, required=("perception", "controller", "out"))
    composed.set_defaults(func=_run_compose, config_cls=PerceiveActConfig)


def _run_train(args) -> int:
    from ..train.common import config_from_args

    try:
        config = config_from_args(args.config_cls, args)
        if args.algorithm == "bc":
            from ..train.bc import train_bc as train
        else:
            from ..train.ppo import train_ppo as train
        checkpoint = train(config)
    except ValueError as e:
        raise UserError(str(e)) from None
    print(f"checkpoint: {checkpoint}  (aerobench eval --policy {args.algorithm} --checkpoint {checkpoint} ...)")
    return 0


def _run_compose(args) -> int:
    from ..train.common import config_from_args
    from ..train.perceive_act import compose_perceive_act

    try:
        out = compose_perceive_act(config_from_args(args.config_cls, args))
    except ValueError as e:
        raise UserError(str(e)) from None
    print(f"wrote {out}  (aerobench eval --policy perceive_act --checkpoint {out} --inputs vision ...)")
    return 0


def add_pi_init(sub) -> None:
    from ..policies.pi_init import add_arguments

    p = sub.add_parser("pi-init", help="a pi0/pi0.5 folder for lerobot-train --policy.path: local weights or a tiny random one")
    add_arguments(p)
    p.set_defaults(func=_run_pi_init)


def _run_pi_init(args) -> int:
    from ..envs.tasks import snake_name
    from ..export.layout import read_dataset_meta
    from ..policies.pi_init import PiInitConfig, init_pi

    try:
        out = init_pi(PiInitConfig(policy=args.policy, dataset=args.dataset, out=args.out, variant=args.variant,
                                   weights=args.weights, tokenizer=args.tokenizer, seed=args.seed))
    except ValueError as e:
        raise UserError(str(e)) from None
    meta = read_dataset_meta(Path(args.dataset)) or {}
    setting = meta.get("generation", {}).get("setting", "TidyHouse")
    config = f"configs/{args.policy}_{snake_name(setting)}.json"
    print(f"wrote {out}  (lerobot-train --config_path {config} --policy.path {out} --dataset.root {args.dataset} ...)")
    return 0

