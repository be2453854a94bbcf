"""
Config for the Diffusion Policy algorithm (veragmil_suite.learning.algos.diffusion_policy).

Its defaults are robomimic 0.5's template for the algorithm (``exps/templates/diffusion_policy.json`` there) for
every key robomimic 0.3.0's configs have: AdamW at 1e-4 with a cosine decay stepped every batch after 500 warm-up
steps, observation horizon 2, action horizon 8, prediction horizon 16, a U-Net of widths 256-512-1024, an EMA of the
weights, DDPM with 100 steps. As there, ``train.frame_stack`` and ``train.seq_length`` keep the base config's 1:
a config that trains sets them from the horizons (configs/json/diffusion_policy.json; the algorithm says which
values it needs).
"""

from __future__ import annotations

from robomimic.config.base_config import BaseConfig


class DiffusionPolicyConfig(BaseConfig):
    ALGO_NAME = "diffusion_policy"

    def algo_config(self) -> None:
        """
        This function populates the `config.algo` attribute of the config, and is given to the `Algo` subclass
        (DiffusionPolicyUNet) through the `algo_config` argument to the constructor.
        """

        # optimization parameters
        self.algo.optim_params.policy.optimizer_type = "adamw"
        self.algo.optim_params.policy.learning_rate.initial = 1e-4  # policy learning rate
        self.algo.optim_params.policy.learning_rate.decay_factor = 0.1  # LR decay factor (multistep, linear only)
        self.algo.optim_params.policy.learning_rate.step_every_batch = True  # step the LR scheduler every batch
        self.algo.optim_params.policy.learning_rate.scheduler_type = "cosine"  # cosine decay to 0 over training
        self.algo.optim_params.policy.learning_rate.num_cycles = 0.5  # cosine cycles over training (0.5: to 0)
        self.algo.optim_params.policy.learning_rate.warmup_steps = 500  # linear warm-up steps before the decay
        self.algo.optim_params.policy.learning_rate.epoch_schedule = []  # epochs where LR decay occurs (multistep)
        self.algo.optim_params.policy.regularization.L2 = 1e-6  # AdamW weight decay

        # horizons, in control steps
        self.algo.horizon.observation_horizon = 2  # observations the policy sees (the newest and those before)
        self.algo.horizon.action_horizon = 8  # actions executed from each prediction before predicting again
        self.algo.horizon.prediction_horizon = 16  # actions each prediction denoises

        # noise prediction network: a 1D temporal U-Net
        self.algo.unet.enabled = True
        self.algo.unet.diffusion_step_embed_dim = 256  # width of the diffusion step's embedding
        self.algo.unet.down_dims = [256, 512, 1024]  # channels of the U-Net's levels
        self.algo.unet.kernel_size = 5  # temporal convolution kernel
        self.algo.unet.n_groups = 8  # GroupNorm groups

        # exponential moving average of the weights, used for acting (decay warms up as 1 - (1 + step)^-power)
        self.algo.ema.enabled = True
        self.algo.ema.power = 0.75

        # noise schedulers (one is enabled): DDPM
        self.algo.ddpm.enabled = True
        self.algo.ddpm.num_train_timesteps = 100
        self.algo.ddpm.num_inference_timesteps = 100
        self.algo.ddpm.beta_schedule = "squaredcos_cap_v2"
        self.algo.ddpm.clip_sample = True
        self.algo.ddpm.prediction_type = "epsilon"

        # DDIM: the same training, fewer denoising steps when acting
        self.algo.ddim.enabled = False
        self.algo.ddim.num_train_timesteps = 100
        self.algo.ddim.num_inference_timesteps = 10
        self.algo.ddim.beta_schedule = "squaredcos_cap_v2"
        self.algo.ddim.clip_sample = True
        self.algo.ddim.set_alpha_to_one = True
        self.algo.ddim.steps_offset = 0
        self.algo.ddim.prediction_type = "epsilon"
