"""A copy of a BC-RNN checkpoint whose rollouts reset the LSTM's hidden state every N steps instead of the
config's ``algo.rnn.horizon`` (robomimic's BC_RNN.get_action reads it at load; training used ``train.seq_length``).

    python with_rnn_horizon.py IN.pth OUT.pth N
"""

import json
import sys

import torch

source, target, horizon = sys.argv[1], sys.argv[2], int(sys.argv[3])
ckpt = torch.load(source, map_location="cpu")
config = json.loads(ckpt["config"])
print(
    f"{source}: algo {ckpt['algo_name']}, rnn.horizon {config['algo']['rnn']['horizon']}, "
    f"seq_length {config['train']['seq_length']} -> rnn.horizon {horizon}"
)
config["algo"]["rnn"]["horizon"] = horizon
ckpt["config"] = json.dumps(config, indent=4)
torch.save(ckpt, target)
