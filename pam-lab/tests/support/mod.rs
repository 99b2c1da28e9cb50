pub mod hidden_plants;
