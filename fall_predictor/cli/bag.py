"""``fall-predictor repair-bag``: recover the messages of bags whose writer was interrupted."""
from __future__ import annotations

import argparse
from dataclasses import asdict
from pathlib import Path

from fall_predictor.cli.args import emit, fail


def cmd_repair_bag(args) -> int:
    from fall_predictor.data.bag_repair import bags_under, needs_repair, repair_bag
    from fall_predictor.data.bagio import BagError
    from fall_predictor.data.parallel import progress_bar

    try:
        bags = bags_under(args.path)
        todo = [bag for bag in bags if needs_repair(bag)]
        reports = []
        with progress_bar(len(todo), desc='repair', unit='bag', disable=args.json) as bar:
            for bag in todo:
                reports.append(repair_bag(bag))
                bar.update(1)
    except (BagError, OSError) as error:
        return fail('repair-bag', error)
    recovered: dict[str, int] = {}
    for report in reports:
        for topic, n in report.messages.items():
            recovered[topic] = recovered.get(topic, 0) + n
    summary = {
        'bags': len(bags),
        'repaired': len(reports),
        'intact': len(bags) - len(reports),
        'messages_recovered': recovered,
        'bytes_dropped': sum(r.bytes_dropped for r in reports),
        'messages_undecodable': sum(sum(r.undecodable.values()) for r in reports),
        'reports': [asdict(r) for r in reports],
    }
    lines = [f'{len(bags)} bag(s) under {args.path}: {len(reports)} repaired, '
             f'{summary["intact"]} intact']
    for r in reports:
        lines.append(f'  {r.bag}: {sum(r.messages.values())} messages recovered '
                     f'({r.from_torn_chunk} from a torn last chunk), {r.bytes_dropped} of '
                     f'{r.file_bytes} bytes dropped ({r.stop_reason}); damaged file kept as '
                     f'{r.backup}')
        for topic, n in sorted(r.messages.items()):
            lines.append(f'    {topic}: {n}')
        for topic, n in sorted(r.undecodable.items()):
            lines.append(f'    {topic}: {n} complete but undecodable, dropped')
    emit(args, summary, lines)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser('repair-bag', help='recover the messages of bags whose writer was killed',
                       description='Find every bag at or under PATH (a bag directory, a .mcap '
                                   'file, a split recording run_NNN or a directory of '
                                   'recordings) whose metadata.yaml or MCAP footer is missing '
                                   '(its writer was interrupted), and rewrite it in place as a '
                                   'valid bag holding every complete message; the damaged file '
                                   'is kept as <bag>/<name>.mcap.damaged. Intact bags are left '
                                   'alone.')
    p.add_argument('path', type=Path, metavar='PATH', help='bag, .mcap file or directory of bags')
    p.add_argument('--json', action='store_true',
                   help='print one JSON object (messages recovered per topic, bytes dropped)')
    p.set_defaults(func=cmd_repair_bag)
